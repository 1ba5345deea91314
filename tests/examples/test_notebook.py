"""examples/pour_water.ipynb runs from top to bottom in a real kernel and shows what it says."""

from __future__ import annotations

from pathlib import Path

import pytest

nbclient = pytest.importorskip("nbclient")
nbformat = pytest.importorskip("nbformat")

NOTEBOOK = Path(__file__).resolve().parents[2] / "examples" / "pour_water.ipynb"


@pytest.mark.slow  # starts a kernel and evolves: about 5 s, more where kernels start slowly
def test_pour_water_notebook_runs_and_shows_fsa_history_and_replay() -> None:
    nb = nbformat.read(NOTEBOOK, as_version=4)
    client = nbclient.NotebookClient(nb, timeout=120, kernel_name="python3",
                                     resources={"metadata": {"path": str(NOTEBOOK.parent)}})
    client.execute()  # raises CellExecutionError on an error cell
    outputs = [out for cell in nb.cells if cell.cell_type == "code" for out in cell.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    data = [o.get("data", {}) for o in outputs if o.output_type == "execute_result"]
    svgs = [d["image/svg+xml"] for d in data if "image/svg+xml" in d]
    htmls = [d["text/html"] for d in data if "text/html" in d]
    assert len(svgs) == 2 and all("<svg" in s for s in svgs)  # the reference, the best FSA
    evolution = next(h for h in htmls if "best fitness" in h)
    assert evolution.count("<svg") == 2  # the fitness history and the best FSA
    # the notebook ends on an FSA that holds, and says so with its bounds
    assert "holds at the required 99 %" in evolution and "95 % bounds" in evolution
    printed = "".join(o.get("text", "") for o in outputs if o.output_type == "stream")
    assert "fitness 0 (0 is water in the glass)" in printed
    replay = next(h for h in htmls if "blackboard changes" in h)
    assert "<td>1</td>" in replay and "GraspObject" in replay
