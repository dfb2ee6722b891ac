"""The Python example of the repository's README runs as printed."""

import re

from conftest import ROOT


def test_the_readme_example_runs(tmp_path, monkeypatch):
    text = (ROOT / "README.md").read_text()
    section = text.split("## cps for Python", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    code = code.replace('"experiments/viapoint.toml"', repr(str(ROOT / "experiments" / "viapoint.toml")))
    monkeypatch.chdir(tmp_path)
    scope = {}
    exec(compile(code, "README.md", "exec"), scope)
    assert scope["y"].shape == (301, 2)
    assert scope["res"].fbest <= 1e-8
    assert scope["q"].shape == (100, 7)
    assert (tmp_path / "model.json").is_file()
    assert (tmp_path / "results" / "from-python" / "summary.json").is_file()
