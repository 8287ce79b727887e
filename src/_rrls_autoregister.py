"""Register the rrls environment ids as soon as Gymnasium is imported.

Gymnasium 1.x removed its entry-point plugin system, so ``gym.make("rrls/robust-hopper-v0")``
would otherwise need an explicit ``import rrls``. The ``rrls_autoregister.pth`` file installed
next to this module imports it at interpreter start-up; all it does is put a small finder on
``sys.meta_path`` that waits for the ``gymnasium`` module to finish importing and then calls
``rrls._registration.register_envs`` (which builds no environment and imports nothing heavy).
Set ``RRLS_NO_AUTOREGISTER=1`` to switch it off.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import os
import sys

_TARGET = "gymnasium"


class _RegisterAfterImport(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path=None, target=None):
        if fullname != _TARGET:
            return None
        sys.meta_path.remove(self)  # one shot: find the real spec without recursing
        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        if spec is None or spec.loader is None:
            return spec
        real_exec = spec.loader.exec_module

        def exec_module(module):
            real_exec(module)
            if "rrls._registration" in sys.modules:
                return  # gymnasium is being imported *by* rrls, which registers its ids itself
            try:
                from rrls._registration import register_envs

                register_envs()
            except Exception as exc:  # noqa: BLE001 - never break `import gymnasium`
                import warnings

                warnings.warn(f"rrls could not register its environments: {exc!r}", stacklevel=2)

        spec.loader.exec_module = exec_module
        return spec


if not os.environ.get("RRLS_NO_AUTOREGISTER") and _TARGET not in sys.modules:
    sys.meta_path.insert(0, _RegisterAfterImport())
