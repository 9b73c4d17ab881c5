"""The ``ftsweep`` command line: one module per group of commands over the layers below."""
