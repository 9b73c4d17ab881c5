"""Tools on result cubes and exported files: choose, query, compare, report, optimize, bench, and
the ``ds.ftsweep`` accessor.
"""
