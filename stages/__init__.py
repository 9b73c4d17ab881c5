"""Pure numerical stages of ftsweep (numpy/numba only): surfaces, layouts, compensation,
interpolation, envelope, metrics. "model §N" cites section N of "The model" in README.md, "[n]" its references."""
