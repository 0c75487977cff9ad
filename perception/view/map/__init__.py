"""The map over viewing directions that the moving-head background lives on: its cells, the
lattice of exact lookups and where camera rays fall on it (:mod:`.directions`, compiled in
:mod:`.directions_kernels`)."""
