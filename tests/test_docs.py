"""The documentation: every public name has its API page; the README stays for users.

The build itself (``sphinx -W``, warnings as errors) runs in ``.ci/run``.
"""

import pathlib
import re

import quatarray

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_every_public_name_is_in_the_api_reference():
    listed = set(re.findall(r"^   ([A-Za-z_][\w.]*)$", (ROOT / "docs" / "api.rst").read_text(), flags=re.M))
    missing = sorted(set(quatarray.__all__) - listed)
    assert not missing, f"add to docs/api.rst: {missing}"


def test_readme_is_for_users():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 300
    assert "quatarray demo" in text and "pytest" in text
    assert len(re.findall(r"\bround\b", text)) <= 2  # the development record lives in docs/changelog.md


def test_guide_pages_are_in_the_toctree():
    index = (ROOT / "docs" / "index.md").read_text()
    for page in sorted((ROOT / "docs" / "guide").glob("*.md")):
        assert f"guide/{page.stem}" in index, page.name
