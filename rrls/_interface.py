"""The original RRLS module path ``rrls._interface``, deprecated: use :mod:`rrls.interface`.

Code written for it imports unchanged; each name warns (``DeprecationWarning``) on access.
"""

from __future__ import annotations

from typing import Any

from rrls import interface
from rrls.deprecation import warn_deprecated

#: old name -> its name in rrls.interface (the module keeps no global of these names, so that
#: every access goes through ``__getattr__`` and warns)
_RENAMED = {
    "ModifiedParamsEnv": "ModifiedParamsEnv",
    "ModifiedParams": "ModifiedParamsEnv",
    "check_protocol_modified_params_env": "is_modified_params_env",
}


def __getattr__(name: str) -> Any:
    if name not in _RENAMED:
        raise AttributeError(f"module 'rrls._interface' has no attribute {name!r}")
    new = _RENAMED[name]
    warn_deprecated(f"rrls._interface.{name} is deprecated; use rrls.interface.{new}")
    return getattr(interface, new)


__all__ = ["ModifiedParams", "ModifiedParamsEnv", "check_protocol_modified_params_env"]  # noqa: F822
