"""Where results live: storage places (local or fsspec), Zarr cubes, case logs, the writer's lock,
and atomic small-file writes.
"""
