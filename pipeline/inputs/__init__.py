"""What users bring: catalogs of surfaces, machines and cutting conditions, user surfaces (height
maps, plug-ins), and the trust rules for them.
"""
