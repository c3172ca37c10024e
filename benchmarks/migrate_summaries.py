"""Issue 58, item 3: migrate the committed run summaries once to 0.3's format, so that no reader of a
never-released format stays. Run once from the repository's root, then removed (it is in the history).

- ``n_updates``: summaries written before 0.3 lack it; it is the last ``train/n_updates`` of the run's
  ``progress.csv`` (0 where the log has rows but never that value), as the removed fallback of
  ``results_dir.run_updates`` read it.
- ``NaN``: summaries written before 0.3 hold bare ``NaN`` (not JSON) for a metric that does not apply; 0.3 writes
  ``null``, which ``summary_from_json`` reads back as NaN.
"""

import csv
import glob
import json
import math
from pathlib import Path

from sb3_maddpg.experiments.results_dir import write_json_atomic


def last_updates(progress: Path) -> int | None:
    if not progress.exists():
        return None
    with open(progress, newline="") as file:
        rows = list(csv.DictReader(file))
    if not rows:
        return None
    counts = [row["train/n_updates"] for row in rows if row.get("train/n_updates")]
    return int(float(counts[-1])) if counts else 0


def main() -> None:
    added = nan_free = left = 0
    for name in sorted(glob.glob("benchmarks/**/summary.json", recursive=True)):
        path = Path(name)
        text = path.read_text()
        summary = json.loads(text)
        changed = "NaN" in text
        if summary.get("n_updates") is None:
            updates = last_updates(path.parent / "progress.csv")
            if updates is None:
                left += 1
            else:
                summary["n_updates"] = updates
                added += 1
                changed = True
        if changed:
            write_json_atomic(path, summary)  # strict JSON: NaN as null
            nan_free += "NaN" in text
            assert json.loads(path.read_text(), parse_constant=lambda c: math.nan) is not None
    print(f"n_updates added to {added} summaries ({left} without a progress log left as they are); NaN -> null in {nan_free}")


if __name__ == "__main__":
    main()
