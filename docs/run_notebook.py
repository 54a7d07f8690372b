"""Execute a notebook into a copy with its outputs, for the documentation site.

``python docs/run_notebook.py notebooks/01_quickstart.ipynb docs/_generated/notebooks/`` runs
every cell in a Jupyter kernel in small mode (``COSSERAT_NOTEBOOK_SMALL=1``, the grids the tests
use) and writes the executed copy there; the repository's notebooks stay without outputs.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import nbclient
import nbformat


def main(argv) -> int:
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    source, out_dir = Path(argv[0]), Path(argv[1])
    nb = nbformat.read(source, as_version=4)
    os.environ["COSSERAT_NOTEBOOK_SMALL"] = "1"
    with tempfile.TemporaryDirectory() as cwd:  # files a notebook writes go nowhere
        nbclient.NotebookClient(nb, timeout=1200, kernel_name="python3",
                                resources={"metadata": {"path": cwd}}).execute()
    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / source.name
    tmp = target.with_suffix(".ipynb.tmp")
    nbformat.write(nb, tmp)
    os.replace(tmp, target)
    print(target)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
