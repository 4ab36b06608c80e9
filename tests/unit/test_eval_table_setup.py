"""eval.md's Table 2 never shows the paper's number beside ours when the maps' grid differs from
the grid the detector was trained on without saying so in the row: such a row reads DIFFERS and
leaves the paper's numbers out; a run on its training grid keeps them."""
from xnlos_core.app.evaluation import PAPER_TABLE2, render_markdown


def _run(name: str, differs: list[str]) -> dict:
    metrics = {f"dense.{c}.{k}": 0.05 for c in ("macro", "los", "mnlos", "all") for k in ("f1", "cd")}
    metrics.update({"reconstruction.f1": 0.01, "reconstruction.cd": 50.0})
    agg = {"metrics": metrics, "classified": True, "maps": 4, "time_ms": {}}
    return {"run": 0, "name": name, "detector": "unet", "reconstructor": "mirror", "overall": agg, "families": {},
            "figures": [], "notes": list(differs), "setup_differs": differs, "match_radius_m": 1.0,
            "dataset": {"path": "d", "split": "test"}}


def _row(md: str) -> str:
    (row,) = [ln for ln in md.splitlines() if ln.startswith("| 0 |") and "unet → mirror" in ln]
    return row


def test_a_run_on_another_grid_says_so_in_its_row_and_drops_the_papers_numbers():
    name = "Proposed + UNet"
    macro_paper = f"({PAPER_TABLE2[name][0]:.2f})"
    same = _row(render_markdown({"name": "t", "config": "c", "runs": [_run(name, [])]}))
    assert "as the paper" in same and macro_paper in same
    msg = "UNetDetector on frame: the map has 31 range bins, the checkpoint was trained on 240"
    md = render_markdown({"name": "t", "config": "c", "runs": [_run(name, [msg])]})
    row = _row(md)
    assert "DIFFERS" in row and macro_paper not in row and "0.05" in row
    assert msg in md.split("## Notes", 1)[1]
