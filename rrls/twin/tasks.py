"""Deprecated: :mod:`rrls.twin.catalog`'s former name (it repeated the top-level
``rrls.tasks``). Importing it warns; every name is the catalog's own."""

from rrls.deprecation import warn_deprecated
from rrls.twin.catalog import *  # noqa: F403 - the old module's names, unchanged
from rrls.twin.catalog import __all__  # noqa: F401

warn_deprecated("rrls.twin.tasks is deprecated; use rrls.twin.catalog (the same names)")
