"""Each Python block of the documentation, run as the reader would: from the repository's folder,
with the module of this build on PYTHONPATH. Blocks come from the Markdown (snippets.py)."""

import os
import pathlib
import subprocess
import sys

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).parent))
import snippets  # noqa: E402

ROOT = pathlib.Path(os.environ["CARTESIAN_IMPEDANCE_SOURCE_DIR"]).resolve()
BLOCKS = [b for b in snippets.snippets(ROOT) if b.kind == "docs_python"]


def test_the_docs_have_python_blocks():
    assert len(BLOCKS) >= 2, [str(b) for b in BLOCKS]


@pytest.mark.parametrize("block", BLOCKS, ids=str)
def test_python_block_runs(block):
    result = subprocess.run(["/usr/bin/python3", "-c", block.code], cwd=ROOT, env=os.environ,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, f"{block}:\n{block.code}\n{result.stdout}\n{result.stderr}"
