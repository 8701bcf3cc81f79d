"""The examples in the package's docstrings run as written (``doctest``), imported by their installed names
(``gaitlog.host.…``): collecting the folders directly would import each module a second time as ``host.…``."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest



def _modules() -> list[str]:
    names = ["gaitlog"]
    for sub in ("protocol", "firmware_sim", "host"):
        package = importlib.import_module(f"gaitlog.{sub}")
        names += [package.__name__] + [i.name for i in pkgutil.walk_packages(package.__path__, f"{package.__name__}.")]
    return sorted(names)


@pytest.mark.parametrize("name", _modules())
def test_docstring_examples(name: str) -> None:
    module = importlib.import_module(name)
    tests = [t for t in doctest.DocTestFinder().find(module) if t.examples]
    if not tests:
        return
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    for test in tests:
        runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples in {name} failed (see above)"
