"""ftsweep orchestration: catalogs, case specs, the case runner and the CLI.

Citations in docstrings, messages and exported headers: "model §N, eq. (k)" is section N and
equation k of "The model" in the project's README.md; "[n]" is reference n listed there.
"""

__version__ = "0.1.0"

from ftsweep import accessor as _accessor  # noqa: E402,F401  (registers the ds.ftsweep accessor)
