"""C99 sources of the reference interpolator (docs/controllers.md); package data only."""
