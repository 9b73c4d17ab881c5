"""Pure numerical stages of ftsweep (numpy/numba only): surfaces, layouts, compensation,
interpolation, envelope, metrics. See ../shared/docs/physics.md for the model."""
