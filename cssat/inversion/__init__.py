"""Light-curve inversion (issue 24): the light curve is linear in the satellite's extended
Gaussian image (area × albedo per surface normal), whose sensing matrix is known and real.

:mod:`cssat.inversion.egi`: the geometric sensing operator ``G (T, K)``, ``fibonacci_sphere``
and a mesh's own EGI.
"""

from cssat.inversion.egi import EGIOperator, egi, egi_operator, fibonacci_sphere

__all__ = ["EGIOperator", "egi", "egi_operator", "fibonacci_sphere"]
