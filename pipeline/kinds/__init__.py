"""The program kinds, one subpackage each (docs/architecture.md, "The program-kind contract"):
``table`` (ring and mesh tables), ``spiral``, ``dpath`` and ``fresnel``. A kind's subpackage
holds its request model (``request``), its :class:`~ftsweep.engine.contract.ProgramKind`
value (``kind``), its planner and simulation, its file format and, where it has one, its
study and figures; :mod:`ftsweep.kinds.path_programs` is the file format the path programs
share. Kinds depend on the engine, never the reverse; the registry (:mod:`ftsweep.registry`)
finds them through the entry points of group ``ftsweep.kinds``.
"""
