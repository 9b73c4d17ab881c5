"""The program kinds, one subpackage each (docs/architecture.md, "The program-kind contract"):
``table`` (ring and mesh tables), ``spiral``, ``dpath`` and ``fresnel``. A kind's subpackage
holds its request model (``request``), its :class:`~ftsweep.engine.contract.ProgramKind`
value (``kind``), its planner and simulation, its file format and, where it has one, its
study, figures and command. A kind leans only on the layers below it (the contract, engine,
inputs, stages and the export format machinery of :mod:`ftsweep.exports`) and on no other
kind; the engine finds it through the entry points of group ``ftsweep.kinds``
(:mod:`ftsweep.engine.plugins`), and its commands through those of ``ftsweep.commands``.
"""
