"""Light-curve inversion (issue 24): the light curve is linear in the satellite's extended
Gaussian image (area × albedo per surface normal), whose sensing matrix is known and real.

:mod:`cssat.inversion.egi`: the geometric sensing operator ``G (T, K)``, ``fibonacci_sphere``
and a mesh's own EGI; :mod:`cssat.inversion.recover`: non-negative sparse recovery of the EGI
(NNLS, non-negative OMP, non-negative ℓ1) with photometric weights and the closure constraint.
"""

from cssat.inversion.egi import EGIOperator, egi, egi_operator, fibonacci_sphere
from cssat.inversion.recover import recover_egi

__all__ = ["EGIOperator", "egi", "egi_operator", "fibonacci_sphere", "recover_egi"]
