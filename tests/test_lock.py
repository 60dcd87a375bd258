"""constraints.txt, the lock setup installs from, pins every dependency pyproject.toml names."""

from __future__ import annotations

import re
import tomllib
from importlib import metadata
from pathlib import Path

import pytest
from packaging.requirements import Requirement

ROOT = Path(__file__).parents[1]
#: The extras scripts/setup.sh installs (`make test`: test and piper; `make bench`: test,bench
#: and piper).
EXTRAS = ("test", "bench", "piper")


def normalized(name: str) -> str:
    """A distribution name as PEP 503 compares them (``PyVRML97`` = ``pyvrml97``)."""
    return re.sub(r"[-_.]+", "-", name).lower()


def lock() -> dict[str, str]:
    """constraints.txt as ``{normalized name: version}``; every line must be ``name==version``."""
    pins: dict[str, str] = {}
    for n, line in enumerate((ROOT / "constraints.txt").read_text().splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        m = re.fullmatch(r"([A-Za-z0-9][A-Za-z0-9._-]*)==([A-Za-z0-9.+!_-]+)", line)
        assert m, f"constraints.txt line {n} is not an exact pin name==version: {line!r}"
        name = normalized(m[1])
        assert name not in pins, f"constraints.txt pins {m[1]} twice (line {n})"
        pins[name] = m[2]
    return pins


def declared() -> list[Requirement]:
    """The dependencies, the extras setup installs and the build backend, from pyproject.toml."""
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    project = pyproject["project"]
    reqs = list(project["dependencies"])
    for extra in EXTRAS:
        reqs += project["optional-dependencies"][extra]
    reqs += pyproject["build-system"]["requires"]
    return [Requirement(r) for r in reqs]


def test_every_line_is_an_exact_pin():
    pins = lock()
    assert len(pins) > 20  # the transitive ones are there, not only the direct ones
    assert "pip" in pins  # setup upgrades pip within the lock


@pytest.mark.parametrize("req", declared(), ids=str)
def test_the_lock_pins_every_declared_dependency(req):
    pins = lock()
    name = normalized(req.name)
    assert name in pins, f"{req.name} is in pyproject.toml but not in constraints.txt: make lock"
    assert req.specifier.contains(pins[name], prereleases=True), (
        f"constraints.txt pins {req.name}=={pins[name]}, outside pyproject.toml's "
        f"{req.specifier}: make lock"
    )


def test_the_environment_is_the_locked_one():
    """What the tests run with is what the lock says (setup installed it), for every package
    pyproject.toml names that is installed here."""
    pins = lock()
    off = []
    for req in declared():
        try:
            have = metadata.version(req.name)
        except metadata.PackageNotFoundError:
            continue  # an extra this environment was not set up with
        if have != pins[normalized(req.name)]:
            off.append(f"{req.name} {have} (lock: {pins[normalized(req.name)]})")
    assert not off, f"installed versions differ from constraints.txt: {off}; run scripts/setup.sh"


def test_setup_installs_from_the_lock():
    setup = (ROOT / "scripts/setup.sh").read_text()
    assert "-c constraints.txt" in setup
    assert "constraints.txt" in (ROOT / "Makefile").read_text()
