"""Sweeps: the sweep spec, its run into a cube (resume, growth), and the Dask execution of its
tasks.
"""
