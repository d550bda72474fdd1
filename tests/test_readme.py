"""The README's embedding example runs as written, and its two commands are what CI runs."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text()


def _python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", README, flags=re.S)


def test_embedding_example_runs():
    blocks = [b for b in _python_blocks() if "run_until" in b]
    assert blocks, "README lost its embedding example"
    out = subprocess.run([sys.executable, "-c", blocks[0]], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.strip().splitlines()
    assert lines[0].startswith("t=120 s coverage=")
    assert "'B2': 'crashed'" in lines[1] and "'A9': 'alive'" in lines[1]
    assert "'crash': 1" in lines[2] and "'drop':" in lines[2]
    assert lines[3].startswith("[(")  # the found events, by UAV name


def test_ci_runs_the_readme_test_command():
    bash_blocks = re.findall(r"```bash\n(.*?)```", README, flags=re.S)
    test_cmd = [line for b in bash_blocks for line in b.splitlines() if "pytest" in line and not line.startswith("#")]
    assert len(test_cmd) == 1
    assert test_cmd[0].strip() in (ROOT / ".ci" / "run").read_text()
