"""Kernels loaded from the cache keep their LLVM IR as bytes until something links them.

numba keeps, beside the machine code of each kernel it loads from its cache, the kernel's LLVM
IR parsed into a module: what it links into a function compiled later that calls the kernel. A
process that finds every kernel in the cache (the daemon on any run but a machine's first)
compiles nothing and never reads those modules, yet they were half of what the loaded kernels
took: after :func:`percept.perception.warm.warm_up` 26 MB of parsed modules for 52 kernels,
whose bitcode is 3 MB. :class:`LazyLinkingLibrary` keeps the bitcode and parses it on the first
link that asks for it; the machine code, what a call runs, is loaded as before.

Like :mod:`.locator`, this extends a part of numba that is not its public interface (its code
library's ``_unserialize`` and ``_get_module_for_linking``); the tests load a cached kernel and
compile a new function that links it.
"""

from __future__ import annotations

from llvmlite import binding as ll
from numba.core.codegen import JITCodeLibrary, JITCPUCodegen


class LazyLinkingLibrary(JITCodeLibrary):
    """numba's JIT code library, whose IR for linking is parsed only when first linked."""

    _linking_bitcode: bytes | None = None
    """The cached IR of a library loaded from the cache, until something links it."""

    @classmethod
    def _unserialize(cls, codegen: JITCPUCodegen, state: tuple[str, str, object]) -> JITCodeLibrary:
        library = super()._unserialize(codegen, state)
        _name, kind, data = state
        if kind == "object" and isinstance(data, tuple):
            # numba parsed the bitcode to note the symbols it defines; it may go now.
            library._linking_bitcode = data[1]
            library._shared_module = None
        return library

    def _get_module_for_linking(self) -> ll.ModuleRef:
        if self._shared_module is None and self._linking_bitcode is not None:
            self._shared_module = ll.parse_bitcode(self._linking_bitcode)
            self._linking_bitcode = None
        return super()._get_module_for_linking()


def install() -> None:
    """Make the libraries of numba's JIT (the CPU target's, what ``njit`` compiles and loads)
    :class:`LazyLinkingLibrary`; before the first kernel is loaded."""
    JITCPUCodegen._library_class = LazyLinkingLibrary
