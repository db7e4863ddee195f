"""`python -m octoroach_model X ...`: the same programs as `ros2 run octoroach_model X`."""
import sys

from octoroach_model.cli import dispatch

if __name__ == '__main__':   # worker processes re-import this module: they must not run X
    sys.exit(dispatch(sys.argv[1:]))
