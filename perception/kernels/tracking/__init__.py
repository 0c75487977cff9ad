"""Kernels of the anchors: association, the box filters, the correction after the association, the
motion inside boxes, the memory's overlaps of boxes."""
