"""Print a summary table of geoproc JSON reports: ``python -m geoproc_cli.report_table DIR``.

Used by ``make demo``; reads every ``*.json`` in DIR that is a geoproc report.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from rich.console import Console
from rich.table import Table
from rich.text import Text

HEADLINE = (
    "mean_relative_error", "pearson_r", "rmse", "mae", "max_abs_error", "bias",
    "mean_normal_angle_deg", "flipped_faces", "hausdorff", "f1", "precision", "recall",
    "pairs_kept", "pairs_removed", "max_abs_change", "steps_per_second",
    "genus", "euler_characteristic", "components", "boundary_loops", "vertices", "faces",
)
SKIP_PREFIXES = ("input_", "merged_", "removed_", "triangulated_")


def headline_metrics(metrics: dict) -> list[tuple[str, float]]:
    """Numeric metrics, the well-known accuracy/topology names first."""
    numeric = {k: v for k, v in metrics.items()
               if isinstance(v, int | float) and not isinstance(v, bool) and not k.startswith(SKIP_PREFIXES)}
    first = [(k, numeric[k]) for k in HEADLINE if k in numeric]
    rest = [(k, v) for k, v in numeric.items() if k not in HEADLINE]
    return first + rest


def summary_table(folder: Path, max_metrics: int = 5) -> Table:
    """One row per report in ``folder``: command, input, a few metrics, total time."""
    t = Table(title=Text(f"geoproc reports in {folder}"))
    for col in ("report", "command", "input", "metrics", "total s"):
        t.add_column(col)
    for path in sorted(folder.glob("*.json")):
        try:
            rep = json.loads(path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError):
            continue
        if not isinstance(rep, dict) or "command" not in rep or "metrics" not in rep:
            continue
        shown = [
            f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
            for k, v in headline_metrics(rep["metrics"])
        ][:max_metrics]
        inputs = ", ".join(Path(i["path"]).name for i in rep.get("inputs", []))
        t.add_row(Text(path.name), Text(str(rep["command"])), Text(inputs), Text(" ".join(shown)),
                  f"{rep.get('timings_s', {}).get('total', float('nan')):.2f}")
    return t


def main(argv: list[str]) -> int:
    folder = Path(argv[1]) if len(argv) > 1 else Path("out/demo")
    console = Console()
    if not console.is_terminal:
        console = Console(width=160)
    console.print(summary_table(folder))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
