"""The program kinds, one subpackage each (docs/architecture.md, "The program-kind contract"):
``table`` (ring and mesh tables), ``spiral``, ``dpath`` and ``fresnel``. A kind's subpackage
face holds its class, a subclass of :class:`~ftsweep.engine.contract.ProgramKind` that loads
no kernel; its modules hold its names (``names``), request model (``request``), planner
(``kind``), simulation, file format, options and, where it has one, its study, figures and
command. A kind leans only on the layers below it (the contract, engine, inputs, stages and
the export format machinery of :mod:`ftsweep.exports`) and on no other kind; the engine finds
it through its one entry point of group ``ftsweep.kinds`` (:mod:`ftsweep.engine.plugins`),
and its options and commands through its class.
"""
