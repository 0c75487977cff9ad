"""The AprilTag C library through ``pupil-apriltags``, released in the right order.

pupil-apriltags (1.0.4.post11, the newest) frees a detector's tag families before the detector,
and the library's ``apriltag_detector_destroy`` then clears the families' decoding tables through
those freed families: it reads a pointer from freed memory and writes NULL into it (valgrind:
an invalid write of 8 bytes in ``quick_decode_uninit``, 64 bytes into the freed 72-byte
``tag36h11`` family). Those 8 bytes are the next heap chunk's size field whenever glibc has put
the freed family in a bin that keeps one, so whether a process aborts ("corrupted size vs.
prev_size"), crashes at a later ``malloc`` or goes on depends on what the heap held: every
detector dropped (a daemon reconfigured, a benchmark's detectors replaced) could crash the
process some time later. The same fix is in the library's duckietown fork
(duckietown/lib-dt-apriltags, pull request 26): the detector is freed first, then its families.
"""

from __future__ import annotations

from pupil_apriltags import Detector


class AprilTagLibrary(Detector):
    """pupil-apriltags' ``Detector``, whose C objects are freed detector first."""

    def __del__(self) -> None:
        detector = getattr(self, "tag_detector_ptr", None)
        if detector is None:  # its __init__ failed before creating one
            return
        self.tag_detector_ptr = None  # the base class's __del__, if called, does nothing
        self.libc.apriltag_detector_destroy.restype = None
        self.libc.apriltag_detector_destroy(detector)
        for name, family in self.tag_families.items():
            destroy = getattr(self.libc, f"{name}_destroy")
            destroy.restype = None
            destroy(family)
