"""Deprecated: :mod:`rrls.twin.agreement`'s former name (it repeated the top-level
``rrls.check``). Importing it warns; every name is the agreement module's own."""

from rrls.deprecation import warn_deprecated
from rrls.twin.agreement import *  # noqa: F403 - the old module's names, unchanged
from rrls.twin.agreement import __all__  # noqa: F401

warn_deprecated("rrls.twin.check is deprecated; use rrls.twin.agreement (the same names)")
