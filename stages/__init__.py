"""Pure numerical stages of ftsweep (numpy/numba only): surfaces, layouts, compensation,
interpolation, envelope, metrics, estimate. This package's source is the repository's
``stages/`` folder, installed as ``ftsweep.stages`` (``stages/envelope.py`` is
``ftsweep.stages.envelope``). "model §N" cites section N of "The model" in
README.md, "[n]" its references."""
