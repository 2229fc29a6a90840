"""Run the ```python blocks of a document as written: in order, in one namespace, warnings quiet."""

import os
import re
import warnings

ROOT = os.path.join(os.path.dirname(__file__), "..")


def read(relpath: str) -> str:
    with open(os.path.join(ROOT, relpath), encoding="utf-8") as fh:
        return fh.read()


def run_python_blocks(text: str, label: str, *, min_blocks: int) -> dict:
    """Execute every ```python block of ``text`` (at least ``min_blocks``); returns the namespace."""
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert len(blocks) >= min_blocks, f"{label}: {len(blocks)} python blocks, expected at least {min_blocks}"
    namespace = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for i, block in enumerate(blocks):
            exec(compile(block, f"{label} block {i}", "exec"), namespace)
    return namespace
