"""What the package says about itself: an MIT licence that a built package carries, a citation of
the method's source, one lock for the runtime and every extra, and no GPL binary in the runtime."""

from __future__ import annotations

import tomllib
from pathlib import Path

import yaml
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).resolve().parent.parent
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]


def test_the_licence_is_the_one_pyproject_names_and_ships_with_the_package():
    assert PROJECT["license"] == "MIT" and PROJECT["license-files"] == ["LICENSE"]
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("MIT License") and "Permission is hereby granted, free of charge" in text
    assert PROJECT["authors"] and PROJECT["classifiers"]


def test_the_citation_names_the_seed_paper_as_the_methods_source():
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0" and cff["type"] == "software" and cff["license"] == "MIT"
    assert cff["version"] == PROJECT["version"]
    paper = cff["references"][0]
    assert paper["title"] == "Multiform adaptive robot skill learning from humans"
    assert [a["family-names"] for a in paper["authors"]] == ["Zhao", "Lawhorn", "Patil", "Susanibar", "Lu",
                                                              "Wang", "Ouyang"]


def test_one_lock_pins_the_runtime_and_every_extra():
    pins = {}
    for line in (ROOT / "requirements.lock").read_text().splitlines():
        if line and not line.startswith("#"):
            name, _, version = line.partition("==")
            pins[canonicalize_name(name)] = version
    wanted = list(PROJECT["dependencies"]) + [r for extra in PROJECT["optional-dependencies"].values() for r in extra]
    for text in wanted:
        req = Requirement(text)
        name = canonicalize_name(req.name)
        assert name in pins, f"{req.name} is not in requirements.lock (make lock)"
        assert req.specifier.contains(pins[name], prereleases=True), f"{req.name}=={pins[name]} outside {req.specifier}"
    makefile = (ROOT / "Makefile").read_text()
    assert all(extra in makefile for extra in PROJECT["optional-dependencies"])   # `make test` installs them all


def test_the_runtime_ships_no_ffmpeg_of_its_own():
    names = {canonicalize_name(Requirement(r).name) for r in PROJECT["dependencies"]}
    assert "imageio-ffmpeg" not in names and "moviepy" not in names
    assert "imageio" not in (ROOT / "src" / "multiform" / "report" / "video.py").read_text()
