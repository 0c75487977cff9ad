"""The light of a frame against the calibration's: a gain and offset per channel fitted on pixels
that are background with confidence (:mod:`.photometric`, compiled in :mod:`.photometric_kernels`
with the robust medians of :mod:`.order_kernels`), and sudden changes that the fit reveals, a lamp
switched or an exposure step (:mod:`.change`)."""
