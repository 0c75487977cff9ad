"""Kernels of the marker detector (:mod:`percept.perception.landmarks`): the grey levels and
edge fits of candidate quads, the sensor noise of a picture."""
