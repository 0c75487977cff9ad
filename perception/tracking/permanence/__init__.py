"""Object permanence: anchors remembered while out of view or hidden behind a nearer object
(:mod:`.memory`), with the box geometry it needs each frame compiled (:mod:`.memory_kernels`)."""
