"""Connected foreground regions: the labelling of a 0/1 mask in raster order with union-find
(:mod:`.forest_kernels`, shared with the colour split's cutting), each region's box, pixel count,
pixels and colour histograms (:mod:`.regions_kernels`), and the record that holds them
(:mod:`.regions`)."""
