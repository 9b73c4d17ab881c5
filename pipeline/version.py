"""The version of ftsweep, in a module of its own so that any module can name it without
importing the package's ``__init__`` (which registers the xarray accessor)."""

__version__ = "0.1.0"
