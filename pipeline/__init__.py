"""ftsweep orchestration: catalogs, case specs, the case runner and the CLI."""

__version__ = "0.1.0"


def __getattr__(name: str):  # pragma: no cover - convenience for notebooks
    raise AttributeError(name)


from pipeline import accessor as _accessor  # noqa: E402,F401  (registers the ds.ftsweep accessor)
