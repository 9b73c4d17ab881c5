"""Tables (model §2): ring and mesh layouts, their controller header, its C view, and the
first-order estimate of a sweep plane.
"""
