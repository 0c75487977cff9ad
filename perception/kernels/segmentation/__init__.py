"""Kernels of the regions and the colour split: labelling, per-region statistics, pieces of each
colour model, percepts merged."""
