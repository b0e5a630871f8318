"""A numba compiler pipeline that tells LLVM a function's arrays do not overlap:
:class:`NoAliasCompiler`.

LLVM vectorises a loop that loads from some arrays through computed indices (per-state table
lookups) and stores into others only when it knows the two cannot share memory: it cannot
check a gathered load's addresses at run time ("cannot identify array bounds"), so without
that knowledge the loop stays scalar. numba has the flag that says it (``noalias``, which marks
every pointer argument of the compiled function ``noalias``), but sets it only for the bodies
of its parallel loops; ``@njit`` does not expose it. ``@njit(pipeline_class=NoAliasCompiler)``
sets it for one function. The promise is the caller's: no array the function writes may share
memory with another of its array arguments (read-only arrays may share memory with each other).

It is not for functions that are inlined into others (``inline="always"``): numba inlines
them before LLVM sees their arguments, and the promise is lost.
"""

from __future__ import annotations

from numba.core.compiler import Compiler

__all__ = ["NoAliasCompiler"]


class NoAliasCompiler(Compiler):
    """numba's standard pipeline, compiling with the ``noalias`` flag set (every pointer
    argument of the LLVM function, array data pointers among them, marked ``noalias``)."""

    def define_pipelines(self):
        self.state.flags.noalias = True
        return super().define_pipelines()
