"""The one simulator (model §3–§6): a case's spec, its planning, its cost, the line sampling, the
record, and the threads and allocator it runs with. It knows no kind by name: each function is
handed the kind's :class:`ftsweep.engine.contract.ProgramKind`.
"""
