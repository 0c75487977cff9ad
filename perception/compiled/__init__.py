"""Compiled kernels of the per-frame core: the loops over regions, pixels and objects.

At 176x144 a frame of the perception core used to be some 250 numpy and OpenCV calls of 1-3 µs
each; the steps done per region, per object and per candidate now run as a few loops compiled by
numba, one call per step. Each stage keeps its kernels beside the module they serve, in a file
named after it with ``_kernels`` (``tracking/anchors.py`` and ``tracking/anchors_kernels.py``):

- ``segmentation/``: the regions' labelling, boxes, counts and histograms, the colour split,
  percepts merged;
- ``tracking/``: association, the box filters, the anchors' correction, the motion in their
  boxes, the anchors' memory;
- ``light/``: the light adaptation's photometric fit, shadow and ghost tests, masks and
  maintenance;
- ``view/``: the moving head's background brought into a frame's view, and its learning;
- ``landmarks/``: the marker detector's steps per candidate quad and its noise estimate;
- ``features/``: the outlines of the solids the sensory experience's footprint fit measures.

This package holds what they all use: :data:`jit`, :data:`fma`, the cache, and
:mod:`.boxes_kernels`, the pixels a box covers and whether it reaches the border.

The other passes over the whole image stay single OpenCV calls, which are faster; the labelling
is not one of them, as most of a frame is background, which the regions' kernel skips eight
pixels at a time.

Every kernel is compiled on its first call (``cache=True``) and the machine code is kept in the
user's cache folder, ``$XDG_CACHE_HOME/percept/numba/<digest>`` (``~/.cache/percept/numba/...``),
not in the installed package, which may be read-only: a machine compiles once, later processes
load the code in well under a second. The digest is that of the kernels' sources
(:func:`sources_digest`): numba tells a cached kernel is out of date by its own file alone, so a
kernel whose file did not change kept the old code of a kernel it calls from another file that
did (an upgrade that changed only :mod:`.boxes_kernels` left the anchors' correction on the old
border rule). Inside it a kernel's code is filed by its place in the perception package, not on the
disk (:mod:`.locator`), so a second install location of the same version loads what the first
compiled. A ``NUMBA_CACHE_DIR`` set by the user is left as it is. This module is the first to import
numba, so the cache folder is chosen before numba reads it.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable
from pathlib import Path
from typing import cast

import numpy as np


def kernel_sources(folder: Path = Path(__file__).parent.parent) -> list[Path]:
    """The files of the compiled code below the perception package ``folder``: this package's
    and every stage's ``*_kernels.py``, sorted."""
    here = folder / "compiled"
    return sorted({*here.rglob("*.py"), *folder.rglob("*_kernels.py")})


def sources_digest(folder: Path = Path(__file__).parent.parent) -> str:
    """Sixteen hex digits of the SHA-256 of the kernels' sources (:func:`kernel_sources` below
    the perception package ``folder``, by path and content): what the compiled code was made
    from. The kernels call nothing but each other and numpy, whose version numba's cache checks
    itself."""
    digest = hashlib.sha256()
    for path in kernel_sources(folder):
        digest.update(path.relative_to(folder).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def cache_folder() -> Path:
    """Where compiled kernels are kept unless ``NUMBA_CACHE_DIR`` says otherwise."""
    base = os.environ.get("XDG_CACHE_HOME", "")
    # The XDG specification says to ignore a relative path.
    root = Path(base) if os.path.isabs(base) else Path.home() / ".cache"
    return root / "percept" / "numba" / sources_digest()


if "NUMBA_CACHE_DIR" not in os.environ:
    os.environ["NUMBA_CACHE_DIR"] = str(cache_folder())

import numba  # noqa: E402  (after the cache folder is set: numba reads it on import)
import numba.extending  # noqa: E402

from percept.perception.compiled import linking, locator  # noqa: E402

locator.install()  # one compilation for every install location (see its module)
linking.install()  # a loaded kernel's IR parsed only if something links it (see its module)

jit = numba.njit(cache=True, nogil=True)
"""The decorator of every kernel: compiled without the interpreter, cached on disk, exact
floating point (no fast-math, so sums and products come out as numpy's)."""


def _fused(typingctx: object, a: object, b: object, c: object) -> tuple[object, object]:
    """The typing and code of :data:`fma` (numba's intrinsic: LLVM IR built for the call)."""
    float32 = numba.types.float32

    def codegen(context: object, builder: object, sig: object, args: list[object]) -> object:
        return builder.fma(*args)  # type: ignore[attr-defined]

    return float32(float32, float32, float32), codegen


fma = cast(
    "Callable[[np.float32, np.float32, np.float32], np.float32]",
    numba.extending.intrinsic(_fused),
)
"""``a * b + c`` rounded once (float32 arguments), as OpenCV's code compiled for this CPU
computes its per-pixel affine maps (the compiler fuses them): the same product and sum taken in
two roundings differ in the last bit, and so sometimes in a rounded grey level. LLVM's ``fma`` is
the CPU's instruction where it has one, an exact library call elsewhere. Kernels only."""
