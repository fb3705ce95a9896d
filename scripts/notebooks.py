"""Run the example notebooks in docs/notebooks/ and save them with their outputs (``bash scripts/dev.sh notebooks``).

Each notebook runs in its own folder (its renders go to docs/notebooks/renders/, which git ignores; the videos and
plots are embedded in the outputs). Progress bars are ipywidgets while a notebook runs; their views are dropped
from the saved outputs, since a saved notebook has no widget state to show them with. The test suite runs them
again with :func:`execute` (tests/test_example_notebooks.py).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import nbformat
from nbclient import NotebookClient

REPO = Path(__file__).resolve().parent.parent
FOLDER = REPO / "docs" / "notebooks"
WIDGET_VIEW = "application/vnd.jupyter.widget-view+json"


def execute(path: Path, workdir: Path | None = None, timeout: float = 600) -> nbformat.NotebookNode:
    """The notebook at ``path`` run from top to bottom in ``workdir`` (default: its folder), with its outputs and
    without widget views. A cell that fails raises nbclient's CellExecutionError, naming the cell."""
    notebook = nbformat.read(path, as_version=4)
    client = NotebookClient(notebook, timeout=timeout, kernel_name="python3",
                            resources={"metadata": {"path": str(workdir or path.parent)}})
    client.execute()
    for cell in notebook.cells:
        if cell.cell_type == "code":
            cell.outputs = [output for output in cell.outputs if WIDGET_VIEW not in output.get("data", {})]
    notebook.metadata.pop("widgets", None)
    return notebook


def main(argv: list[str]) -> int:
    names = argv or sorted(path.stem for path in FOLDER.glob("*.ipynb"))
    for name in names:
        path = FOLDER / f"{name}.ipynb"
        started = time.perf_counter()
        notebook = execute(path)
        nbformat.write(notebook, path)
        print(f"{path.relative_to(REPO)}: run in {time.perf_counter() - started:.1f} s, "
              f"{path.stat().st_size / 1e6:.2f} MB with its outputs")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
