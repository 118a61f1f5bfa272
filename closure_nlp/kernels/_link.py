"""Link a kernel's large callees after its own optimisation, not before.

numba links the optimised code of every kernel a kernel calls into the kernel's own module and
then optimises the whole module again: a kernel such as the branch and bound's ``advance``
spent most of its compile re-optimising the slot game, the cell games and the split, each
already optimised in its own library. A callee this large is not inlined into its caller (its
body stays a function of its own), so it is linked after the caller's optimisation, as its own
library optimised it; small callees, which the optimiser may inline into a loop, are linked
before, as numba does. Only the libraries of this package's kernels are changed; anything else
numba compiles is left alone, and so is a numba whose ``finalize`` is not the one this
replaces (numba 0.63 to 0.68: earlier ones lack its reload-init step).
"""

from __future__ import annotations

# A callee library whose module holds more instructions than this is linked after the
# caller's optimisation (the inliner's threshold is a few hundred: none this large is inlined).
LATE = 1000
_MARK = "11closure_nlp7kernels"  # in the mangled name of every function of this package's kernels
# The digest of numba's own ``CPUCodeLibrary.finalize`` (its syntax tree) that ``finalize``
# below rewrites: any other numba keeps its own.
FINALIZE_DIGEST = "1cf27cb4c518"


def _size(module) -> int:
    return sum(
        sum(1 for block in fn.blocks for _ in block.instructions)
        for fn in module.functions
        if not fn.is_declaration
    )


def digest(function) -> str:
    """The first 12 hex digits of the SHA-1 of ``function``'s syntax tree (its source parsed:
    comments and layout do not count)."""
    import ast
    import hashlib
    import inspect
    import textwrap

    tree = ast.parse(textwrap.dedent(inspect.getsource(function)))
    return hashlib.sha1(ast.dump(tree.body[0]).encode()).hexdigest()[:12]


def install() -> None:
    """Patch numba's JIT code library (once, idempotent); without the private names it
    relies on (another numba), leave numba as it is."""
    try:
        from numba.core import codegen
        from numba.core.compiler_lock import require_global_compiler_lock

        library_class = codegen.JITCodeLibrary
        numba_finalize = library_class.finalize
        needed = ("_optimize_final_module", "_get_module_for_linking", "_finalize_final_module")
        if not all(hasattr(library_class, name) for name in needed):
            return
    except (ImportError, AttributeError):
        return
    if getattr(numba_finalize, "_closure_nlp", False):
        return
    try:
        if digest(numba_finalize) != FINALIZE_DIGEST:
            return
    except (OSError, TypeError, SyntaxError):  # no source to read: not the known one
        return

    def size(library) -> int:
        if getattr(library, "_closure_nlp_size", None) is None:
            library._closure_nlp_size = _size(library._get_module_for_linking())
        return library._closure_nlp_size

    def finalize(self):
        if not any(_MARK in fn.name for fn in self._final_module.functions):
            return numba_finalize(self)
        require_global_compiler_lock()
        self._codegen._check_llvm_bugs()
        self._raise_if_finalized()
        late, seen = [], set()
        for library in self._linking_libraries:
            if library in seen:
                continue
            seen.add(library)
            self._reload_init.update(library._reload_init)
            module = library._get_module_for_linking()
            if size(library) > LATE:
                late.append(module)
            else:
                self._final_module.link_in(module, preserve=True)
        self._optimize_final_module()
        for module in late:
            self._final_module.link_in(module, preserve=True)
        self._final_module.verify()
        self._finalize_final_module()

    finalize._closure_nlp = True
    library_class.finalize = finalize
