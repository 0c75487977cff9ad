"""Kernels of the light adaptation (:mod:`percept.perception.light`): the photometric fit and its
medians, the shadow and ghost tests, the masks and the selective maintenance."""
