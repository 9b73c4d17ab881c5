"""Spiral path programs ([4]): points along the tool's spiral from an error budget."""
