"""`python -m octoroach_model X ...`: the same programs as `ros2 run octoroach_model X`."""
import sys

from octoroach_model.cli import dispatch

sys.exit(dispatch(sys.argv[1:]))
