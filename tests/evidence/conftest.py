"""Fixtures of the evidence tier: the repository's tree and mutated copies of it
(:mod:`mutate`)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))  # mutate.py, for the test modules

from mutate import REPO, CachedTree, Edit, SourceTree, copy_tree


@pytest.fixture(scope="session")
def original(tmp_path_factory) -> SourceTree:
    """The repository as it is: the unmutated side of every comparison."""
    return CachedTree(REPO, tmp_path_factory.mktemp("original"))


@pytest.fixture
def mutant(tmp_path):
    """``mutant(*edits)``: a copy of the tree with ``edits`` applied, its own RTL builds."""

    def make(*edits: Edit) -> SourceTree:
        assert edits, "a mutant needs at least one edit"
        root = copy_tree(tmp_path / "tree", edits)
        return SourceTree(root, tmp_path / "runs", {"HWSIM_RTL_BUILD": str(tmp_path / "rtl")})

    return make
