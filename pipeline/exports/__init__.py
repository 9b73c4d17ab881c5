"""Exported files: one export and one verify for every kind, the sidecar and program-file machinery
they share, and who signed a file.
"""
