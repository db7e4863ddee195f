"""
Size limits of every reader and planner: what the package allocates for any input, at most.

Why: a small hostile or broken file must not take the machine down (a 32 KB MCAP whose chunk
claims 1 GiB decompressed, a 1 MB data set of int8 zeros that widens to 10 GB of float64, a
2 KB metadata.yaml of nested YAML aliases). Every reader checks what a file claims against
these limits *before* it allocates, and says in one line which limit was hit. The values are
far above what a real recording needs; docs/bags.md lists them.
"""
from __future__ import annotations

MIB = 1 << 20

# MCAP: the largest decompressed chunk read (rosbag2 writes chunks of about 1 MiB, this
# package 64 KiB). A chunk that claims more is skipped as unreadable, with a note.
MAX_CHUNK_BYTES = 64 * MIB
# ROS 1 bags: the largest decompressed chunk (rosbag record's default chunk is 768 KiB).
MAX_ROS1_CHUNK_BYTES = 64 * MIB
# .npz data sets: the largest array, counted as the float64 it becomes...
MAX_DATASET_BYTES = 2048 * MIB
# ... and at most this many times the file's own size (np.savez_compressed of real poses
# shrinks them by less than 2; a larger ratio is a decompression bomb)
MAX_DATASET_EXPANSION = 64
# .npz data sets: the JSON text of their info (notes, sources)
MAX_DATASET_INFO_BYTES = 16 * MIB
# metadata.yaml of a bag, and a channel's offered_qos_profiles text
MAX_YAML_BYTES = 4 * MIB
# Vicon CSV: the longest line, in characters (the names line of an export of many markers
# is a few kB); a cell is limited by Python's csv field limit (131072 characters)
MAX_CSV_LINE = 1 * MIB
# motion capture (C3D, Vicon CSV trajectories): markers on one rigid body
MAX_BODY_MARKERS = 256
# folders of inputs: how deep a folder is searched (symbolic links to a folder already on
# the way are never followed again)
MAX_FOLDER_DEPTH = 32
# studies: data sets (tasks) one study may hold
MAX_STUDY_TASKS = 1_000_000
# simulate(): runs x samples per run in one call (about 144 bytes a sample at its peak, so
# some 5.4 GiB; 500 runs of 10 cycles at 50 Hz are 125 500)
MAX_SIMULATED_SAMPLES = 40_000_000


def size_words(count: float) -> str:
    """Say a byte count in MiB or GiB for error messages."""
    if count >= 1024 * MIB:
        return f'{count / (1024 * MIB):.3g} GiB'
    return f'{count / MIB:.3g} MiB'
