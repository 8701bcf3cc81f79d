"""gaitlog: the gait logger of Alvarez et al. (2006) as a golden model, its binary protocol, and the PC side.

Three subpackages, each importing only the ones before it:

``gaitlog.protocol``
    The binary contract between logger and host (frames, header, sample packing, step records, images).
``gaitlog.firmware_sim``
    The logger as a PIC16F877 device and its on-line step algorithm in the PIC's fixed point.
``gaitlog.host``
    The PC side: link, dump, decode, calibrate, the offline M1-M5 chain, studies and the ``gaitlog`` command.

In the repository the three are the top-level folders ``protocol/``, ``firmware_sim/`` and ``host/``;
setuptools' ``package-dir`` installs them under this package.
"""

import os as _os
import sys as _sys
from importlib.machinery import PathFinder as _PathFinder

#: The distribution's version (pyproject.toml reads it from here).
__version__ = "0.6.1"

_SUBPACKAGES = ("protocol", "firmware_sim", "host")


class _CheckoutFinder:
    """Finds ``gaitlog.protocol``, ``gaitlog.firmware_sim`` and ``gaitlog.host`` beside this folder in a source
    checkout, where this folder shadows an installed copy (``python -m gaitlog`` run from the repository's root
    after a non-editable install). Asked last, after every installed finder."""

    def __init__(self, root: str) -> None:
        self.root = root

    def find_spec(self, name, path=None, target=None):
        prefix, _, sub = name.partition(".")
        if prefix != "gaitlog" or sub not in _SUBPACKAGES:
            return None
        return _PathFinder.find_spec(name, [self.root])


_root = _os.path.dirname(_os.path.dirname(_os.path.abspath(__file__)))
if _os.path.isfile(_os.path.join(_root, "pyproject.toml")) and not any(
        isinstance(f, _CheckoutFinder) for f in _sys.meta_path):
    _sys.meta_path.append(_CheckoutFinder(_root))
del _root
