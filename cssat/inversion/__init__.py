"""Light-curve inversion: the light curve is linear in the satellite's extended
Gaussian image (area × albedo per surface normal), whose sensing matrix is known and real.

:mod:`cssat.inversion.egi`: the geometric sensing operator ``G (T, K)``, ``fibonacci_sphere``
and a mesh's own EGI, and ``Lobes`` (an EGI per scattering lobe: diffuse and specular areas per
normal); :mod:`cssat.inversion.recover`: non-negative sparse recovery of the EGI
(NNLS, non-negative OMP, non-negative ℓ1) with photometric weights and the closure constraint;
:mod:`cssat.inversion.shape`: the convex shape of an EGI (Minkowski, Little's program) and
``invert_convex`` from a light curve; :mod:`cssat.inversion.spin`: the period, the tumbling
periods and the pole of a principal-axis spin; :mod:`cssat.inversion.tumble`: the full state of a
tumbling (torque-free) object; :mod:`cssat.inversion.period_methods`: period methods by name
(``register_period_method``, ``find_period``); :mod:`cssat.inversion.results`: the results as
read-only mappings with attributes (``PeriodResult``, ``SpinSolution``, ``TumblingSolution``).
"""

from cssat.inversion.egi import EGIOperator, Lobes, egi, egi_operator, fibonacci_sphere
from cssat.inversion.observability import observability
from cssat.inversion.recover import recover_egi
from cssat.inversion.shape import ConvexInversion, convex_iou, invert_convex, minkowski
from cssat.inversion.frequencies import estimate_tumbling_periods
from cssat.inversion.period import estimate_period
from cssat.inversion.period_methods import find_period, period_method, period_methods, register_period_method
from cssat.inversion.results import PeriodResult, series_fit
from cssat.inversion.spin import SpinSolution, estimate_spin
from cssat.inversion.tumble import TumblingSolution, TumblingState, estimate_tumbling, tumbling_rates

__all__ = ["EGIOperator", "Lobes", "egi", "egi_operator", "fibonacci_sphere", "recover_egi", "minkowski", "invert_convex",
           "ConvexInversion", "observability", "estimate_period", "estimate_spin", "estimate_tumbling_periods",
           "SpinSolution", "convex_iou", "estimate_tumbling", "TumblingSolution", "TumblingState", "tumbling_rates",
           "PeriodResult", "series_fit", "find_period", "period_method", "period_methods", "register_period_method"]
