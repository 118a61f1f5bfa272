"""How the libraries of this package's kernels are linked and compiled to machine code.

numba links the optimised code of every kernel a kernel calls into the kernel's own module and
then optimises the whole module again: a kernel such as the branch and bound's ``advance``
spent most of its compile re-optimising the slot game, the cell games and the split, each
already optimised in its own library. A callee this large is not inlined into its caller (its
body stays a function of its own), so it is linked after the caller's optimisation, as its own
library optimised it; small callees, which the optimiser may inline into a loop, are linked
before, as numba does.

A kernel that only other kernels call (:func:`kernel_only`) has no Python entry, and its
library is never compiled to machine code: numba would compile each library with its whole
linked tree, though only the callers' machine code (each holding its callees) ever runs. Its
library is kept, and cached, as the optimised module its callers link.

Only the libraries of this package's kernels are changed; anything else numba compiles is left
alone, and so is a numba whose ``finalize`` is not the one this replaces (numba 0.63 to 0.68:
earlier ones lack its reload-init step).
"""

from __future__ import annotations

import types

from numba import njit
from numba.core.registry import CPUDispatcher

# A callee library whose module holds more instructions than this is linked after the
# caller's optimisation (the inliner's threshold is a few hundred: none this large is inlined).
LATE = 1000
_MARK = "11closure_nlp7kernels"  # in the mangled name of every function of this package's kernels
_ENTRY = "_ZN7cpython"  # numba's Python entry of a function: its mangled name in this namespace
# How a kernel-only library is cached: the optimised module its callers link, no machine code.
LINKING = "closure_nlp.linking"
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
        from llvmlite import binding as llvm
        from numba.core import codegen
        from numba.core.compiler_lock import require_global_compiler_lock

        library_class = codegen.JITCodeLibrary
        numba_finalize = library_class.finalize
        needed = (
            "_optimize_final_module", "_get_module_for_linking", "_finalize_final_module",
            "_finalize_dynamic_globals", "_verify_declare_only_symbols", "_unserialize",
            "serialize_using_object_code",
        )  # fmt: skip
        llvm_needed = (
            "create_pipeline_tuning_options", "create_new_module_pass_manager",
            "create_pass_builder",
        )  # fmt: skip
        if (
            not all(hasattr(library_class, name) for name in needed)
            or not all(hasattr(llvm, name) for name in llvm_needed)
            or not hasattr(llvm.create_new_module_pass_manager(), "add_loop_strength_reduce_pass")
            or not hasattr(codegen.JITCPUCodegen, "set_env")
        ):
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
        # no Python entry among its own functions: a kernel-only kernel (its callers' code runs)
        linking_only = not any(
            fn.name.startswith(_ENTRY) and not fn.is_declaration
            for fn in self._final_module.functions
        )
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
        if not linking_only:
            self._finalize_final_module()
            return
        # compiling a module to machine code runs the code generator's own passes on it, loop
        # strength reduction among them, and numba links that module into the callers: the
        # callers' code is as fast only with it (4 PCwF certified 1-5% slower per set without)
        tuning = llvm.create_pipeline_tuning_options(3)
        passes = llvm.create_new_module_pass_manager()
        passes.add_loop_strength_reduce_pass()
        passes.run(self._final_module, llvm.create_pass_builder(self._codegen._tm, tuning))
        self._finalize_dynamic_globals()  # numba caches no library that uses them
        self._verify_declare_only_symbols()
        self._closure_nlp_linking = True
        self._finalized = True

    def serialize_using_object_code(self):
        if getattr(self, "_closure_nlp_linking", False):
            return (self.name, LINKING, self._get_module_for_linking().as_bitcode())
        return numba_serialize(self)

    def unserialize(cls, codegen, state):
        name, kind, data = state
        if kind != LINKING:
            return numba_unserialize(cls, codegen, state)
        self = codegen.create_library(name)
        self._shared_module = llvm.parse_bitcode(data)
        self._closure_nlp_linking = True
        self._finalized = True
        return self

    def set_env(self, env_name, env):
        # a kernel-only library is in no engine: no environment to point at (numba would
        # write to address 0)
        if self._engine.is_symbol_defined(env_name):
            numba_set_env(self, env_name, env)

    numba_serialize = library_class.serialize_using_object_code
    numba_unserialize = library_class._unserialize.__func__
    numba_set_env = codegen.JITCPUCodegen.set_env
    finalize._closure_nlp = True
    library_class.finalize = finalize
    library_class.serialize_using_object_code = serialize_using_object_code
    library_class._unserialize = classmethod(unserialize)
    codegen.JITCPUCodegen.set_env = set_env


class KernelOnly(CPUDispatcher):
    """A kernel without a Python entry (:func:`kernel_only`): called from Python, it runs
    ``python``, the same function compiled with its entry (and cached apart) at the first such
    call (tests: the library calls only entry points from Python)."""

    _python = None

    @property
    def python(self):
        if self._python is None:
            f = self.py_func
            copy = types.FunctionType(
                f.__code__, f.__globals__, f.__name__, f.__defaults__, f.__closure__
            )
            copy.__kwdefaults__ = f.__kwdefaults__
            copy.__qualname__ = f"{f.__qualname__}.python"  # its own cache files
            copy.__module__ = f.__module__
            copy.__doc__ = f.__doc__
            self._python = njit(**self.python_options)(copy)
        return self._python

    def __call__(self, *args, **kwargs):
        return self.python(*args, **kwargs)


def kernel_only(**options):
    """``numba.njit(**options)`` for a kernel that only other kernels call: compiled without
    its Python entry (and, with the linking installed, without machine code of its own); a
    :class:`KernelOnly`."""

    def decorate(function):
        kernel = njit(**options, no_cpython_wrapper=True, no_cfunc_wrapper=True)(function)
        kernel.__class__ = KernelOnly  # numba's dispatcher, but for calls from Python
        kernel.python_options = options
        return kernel

    return decorate
