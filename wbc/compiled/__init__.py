"""Compiled (numba) kernels for the solvers' hot path, a leaf of the package (it imports only
:mod:`wbc.exceptions`, :mod:`wbc.types`, numpy and numba): the kernels' one signature
(:mod:`~wbc.compiled.signature`), their building blocks (:mod:`~wbc.compiled.rows`), the
generated tick of a set of kernels that the solvers' plans pass in
(:mod:`~wbc.compiled.dispatch`), and the box/equality least-squares level solver shared by
the weighted and the hierarchical QP."""
