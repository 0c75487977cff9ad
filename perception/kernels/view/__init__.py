"""Kernels of the moving head's background (:mod:`percept.perception.view`): rays to map
coordinates, the bounds brought into a frame's view, the learning of unknown directions."""
