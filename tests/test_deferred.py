"""vtts.deferred: packages put off until used still work in every way they are reached."""

from __future__ import annotations

import subprocess
import sys


def _run(code: str) -> str:
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return r.stdout


def test_numpy_subpackages_wait_until_used():
    out = _run(
        "import sys, vtts, scipy.sparse, numpy as np\n"
        "print(sorted(n for n in ('numpy.f2py', 'numpy.testing', 'numpy.ma')\n"
        "      if type(sys.modules[n]).__name__ == '_DeferredPackage'))\n"
        "np.testing.assert_array_equal(np.arange(3), [0, 1, 2])\n"
        "from numpy.ma import masked_array\n"
        "print(int(masked_array([1, 2, 3], mask=[0, 1, 0]).sum()))\n"
        "import numpy.f2py.crackfortran\n"
        "print(type(sys.modules['numpy.testing']).__name__, callable(np.f2py.run_main))\n"
    )
    assert out.split("\n")[:3] == [
        "['numpy.f2py', 'numpy.ma', 'numpy.testing']",
        "4",
        "module True",
    ]


def test_a_package_imported_first_is_left_alone():
    out = _run(
        "import numpy.testing, sys, vtts\nprint(type(sys.modules['numpy.testing']).__name__)\n"
    )
    assert out.strip() == "module"


def test_defer_package_ignores_what_is_not_a_package():
    out = _run(
        "import sys\n"
        "from vtts.deferred import defer_package\n"
        "defer_package('json.decoder'); defer_package('no_such_package_here')\n"
        "m = sys.modules.get('json.decoder')\n"
        "print('no_such_package_here' in sys.modules, type(m).__name__)\n"
    )
    assert out.strip() == "False module"
