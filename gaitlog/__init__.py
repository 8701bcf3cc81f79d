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

#: The distribution's version (pyproject.toml reads it from here).
__version__ = "0.2.0"

# In a source checkout (``python -m gaitlog`` or ``import gaitlog`` from the repository's root, where this folder
# shadows an installed copy) the subpackages are this folder's siblings.
_checkout = _os.path.dirname(_os.path.dirname(_os.path.abspath(__file__)))
if _os.path.isfile(_os.path.join(_checkout, "pyproject.toml")) and _os.path.isfile(
        _os.path.join(_checkout, "host", "__init__.py")):
    __path__.append(_checkout)  # noqa: F821 (a package's __path__)
del _os, _checkout
