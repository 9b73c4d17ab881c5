"""Pure numerical stages of ftsweep (numpy/numba only): surfaces, layouts, compensation,
interpolation, envelope, metrics, estimate. "model §N" cites section N of "The model" in
README.md, "[n]" its references."""
