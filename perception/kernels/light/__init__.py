"""Kernels of the light adaptation (:mod:`percept.perception.light`): the photometric fit and its
medians, the pass that maps a frame and makes its foreground and shadow tests, the ghost test,
the masks and the selective maintenance."""
