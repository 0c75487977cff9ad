"""Kernels of the sensory experience: the outlines of the solids its footprint fit measures."""
