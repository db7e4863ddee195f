"""
Runs and data sets: pose streams cut into runs on a common grid, and kept in one file.

- `run_set`: `read_runs` and `load_measured` (runs split, cleaned, resampled);
- `dataset`: the portable .npz data set, checked before it is loaded (`npz_check`);
- `duplicates`: the same recording given twice, said in the notes.
"""
