"""The Python examples of the READMEs run as written: the quick start of the repository's
README.md and the tour in the package's own README (crates/rootfuse-py/README.md)."""

import pathlib
import re

import pytest

PACKAGE = pathlib.Path(__file__).resolve().parents[1]
READMES = {"repository": PACKAGE.parents[1] / "README.md", "package": PACKAGE / "README.md"}


@pytest.mark.parametrize("name", sorted(READMES))
def test_readme_python_examples_run(name):
    readme = READMES[name]
    blocks = re.findall(r"```python\n(.*?)```", readme.read_text(), re.S)
    assert blocks, f"{readme} has no ```python block"
    for block in blocks:
        exec(compile(block, str(readme), "exec"), {})
