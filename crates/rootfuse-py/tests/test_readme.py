"""The Python example of README.md runs as written."""

import pathlib
import re

README = pathlib.Path(__file__).resolve().parents[3] / "README.md"


def test_readme_python_example_runs():
    text = README.read_text()
    section = text[text.index("## Python"):]
    match = re.search(r"```python\n(.*?)```", section, re.S)
    assert match, "README.md has no ```python block in its Python section"
    exec(compile(match.group(1), "README.md", "exec"), {})
