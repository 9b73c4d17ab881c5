"""ftsweep orchestration: catalogs, case specs, the case runner and the CLI."""

__version__ = "0.1.0"
