"""Freeform Fresnel programs on an X-Y-Z-C lathe ([2]): the kind, its planner, its form simulation
and study.
"""
