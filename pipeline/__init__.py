"""ftsweep orchestration: catalogs, case specs, the case runner and the CLI."""

__version__ = "0.1.0"

from ftsweep import accessor as _accessor  # noqa: E402,F401  (registers the ds.ftsweep accessor)
