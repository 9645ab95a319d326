"""Old import path of :mod:`quatarray.layouts` and of the modified Rodrigues
parameters and Gibbs vectors, now in :mod:`quatarray.conversions`.

A small module that only re-exports (not an alias of one module object, as
the old module held both): ``from quatarray.representations import as_xyzw,
as_mrp`` gives the same functions as ``quatarray.layouts.as_xyzw`` and
``quatarray.conversions.as_mrp``. Any other name of the old module is looked
up in :mod:`quatarray.layouts`, then among the moved MRP and Gibbs names of
:mod:`quatarray.conversions`.
"""

from . import conversions as _conversions
from . import layouts as _layouts
from .conversions import as_gibbs, as_mrp, from_gibbs, from_mrp
from .layouts import (
    as_left_matrix, as_right_matrix, as_su2, as_xyzw, from_scipy, from_su2, from_xyzw, to_scipy,
)  # fmt: skip

__all__ = [
    "as_xyzw", "from_xyzw", "to_scipy", "from_scipy", "as_left_matrix", "as_right_matrix",
    "as_su2", "from_su2", "as_mrp", "from_mrp", "as_gibbs", "from_gibbs",
]  # fmt: skip

# the old module's MRP and Gibbs code, moved to quatarray.conversions
_MOVED = {
    "qmrp", "qmrp_raw", "mrp_quat", "qgibbs", "gibbs_quat",
    "_as_mrp_plain", "_as_mrp", "_from_mrp", "_as_gibbs", "_from_gibbs",
}  # fmt: skip


def __getattr__(name):
    if name in _MOVED:
        return getattr(_conversions, name)
    try:
        return getattr(_layouts, name)
    except AttributeError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
