"""D-shaped slow-tool-servo paths ([5]): the kind, its planner and simulation, its study and
figures.
"""
