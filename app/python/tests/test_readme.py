"""The README's Python example, as a user pastes it into a fresh virtual environment with the
wheel installed (this one)."""

import re
import subprocess
import sys
from pathlib import Path

README = Path(__file__).resolve().parents[3] / "README.md"


def test_the_readme_python_example_runs(tmp_path):
    text = README.read_text()
    section = text[text.index("## Python") :]
    match = re.search(r'python -c "([^"]+)"', section)
    assert match, "the README's Python section shows a `python -c` example"
    done = subprocess.run([sys.executable, "-c", match.group(1)], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    rate = float(done.stdout.strip().splitlines()[-1])
    assert 0.5 < rate <= 1.0
    assert (tmp_path / "out/py_stack.hdf5").is_file()
