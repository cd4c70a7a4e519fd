"""The problem a solver is handed (:class:`cssat.sparse.problem.Problem`, re-exported: it lives in
the generic sparse layer, so a domain package can hand a problem to any solver without importing
the solver registry)."""

from cssat.sparse.problem import Problem

__all__ = ["Problem"]
