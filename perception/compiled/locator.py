"""Where numba keeps a kernel's machine code: by the kernel's place inside the perception package,
not on the disk, so that every install location of one version shares one compilation.

numba's own locator files a kernel's code under a digest of the absolute folder of its source
file: each new virtual environment or checkout compiled every kernel again (42-62 s of CPU), with
the cache already full from the last one. :class:`PackageLocator` files it under the kernel's
folder relative to the perception package instead (``kernels_segmentation``...), inside the cache
folder that :mod:`percept.perception.compiled` keys by the digest of all the kernels' sources, and
tells a kernel's code is out of date by its source file's content (older numba versions compared its
modification time, which every install sets anew). numba's other checks stay as they are: the
kernel's bytecode, its argument types, the CPU and numba's own version.
"""

from __future__ import annotations

import functools
import hashlib
import os
from collections.abc import Callable
from pathlib import Path

from numba.core import config
from numba.core.caching import CacheImpl, _CacheLocator

PACKAGE = Path(__file__).resolve().parent.parent
"""The perception package's folder, which holds every kernel, wherever this install put it."""


def _cache_dir() -> str:
    """numba's cache folder (``NUMBA_CACHE_DIR``, read by numba's configuration; "" unset)."""
    folder: str = getattr(config, "CACHE_DIR", "")
    return folder


@functools.cache
def _content_stamp(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


class PackageLocator(_CacheLocator):
    """numba's cache locator for the functions defined in the perception package's files."""

    def __init__(self, py_func: Callable[..., object], py_file: str) -> None:
        self._source = Path(py_file).resolve()
        self._lineno = py_func.__code__.co_firstlineno
        inside = self._source.relative_to(PACKAGE).parent.parts
        self._cache_path = os.path.join(_cache_dir(), "_".join(("kernels", *inside)))

    def get_cache_path(self) -> str:
        return self._cache_path

    def get_source_stamp(self) -> str:
        return _content_stamp(self._source)

    def get_disambiguator(self) -> str:
        return str(self._lineno)

    @classmethod
    def from_function(cls, py_func: Callable[..., object], py_file: str) -> PackageLocator | None:
        """The locator of a kernel of the perception package (None for any other function, and when
        no cache folder is set or it cannot be written: numba's own locators decide then)."""
        if not _cache_dir() or not Path(py_file).resolve().is_relative_to(PACKAGE):
            return None
        locator = cls(py_func, py_file)
        try:
            locator.ensure_cache_path()
        except OSError:
            return None
        return locator


def install() -> None:
    """Ask numba to try :class:`PackageLocator` first (once; numba reads the list for each
    function it caches)."""
    locators = CacheImpl._locator_classes
    if PackageLocator not in locators:
        locators.insert(0, PackageLocator)
