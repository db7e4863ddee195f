"""Suite-wide isolation: each test process gets its own ROS domain, on localhost only.

Parallel runs (pytest-xdist workers, two CI jobs on one machine) must never hear each other,
so the domain id comes from the worker and the process id. Child processes started by tests
inherit these variables.
"""
from __future__ import annotations

import os

import matplotlib

matplotlib.use('Agg')


def _isolated_domain_id() -> int:
    worker = os.environ.get('PYTEST_XDIST_WORKER', 'gw0')
    worker_index = int(''.join(ch for ch in worker if ch.isdigit()) or 0)
    # Fast DDS with LOCALHOST range accepts domain ids 0..232; keep clear of 0 (the default).
    return 1 + (os.getpid() * 7 + worker_index * 31) % 200


os.environ['ROS_DOMAIN_ID'] = str(_isolated_domain_id())
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('MPLBACKEND', 'Agg')
