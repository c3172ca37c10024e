"""
Record what trained the sweep's runs that finished before runs recorded it themselves (commit 2475060).

The report's cost table (``cost.md``) gives core-hours only for runs whose ``summary.json`` says what trained them
(``device``, ``torch_threads``, ``runs_trained_together``); the 13 runs finished from commits d52d018 and 3431bf4
predate those fields. Every start of this sweep ran ``run.sh``, which trains each run alone in its own process with one
torch thread on the CPU (``--threads 1``, the local backend), and each start's line in ``sweep.log`` says so
("on local with 2 worker(s) x 1 thread(s)"). This script checks every such line, then writes those fields into the
summaries that lack them, with ``resources_recorded`` saying where they came from. Runs that record them are left as
they are.

    python benchmarks/paper_n5/record_resources.py benchmarks/paper_n5/results
"""

import argparse
import json
import re
from pathlib import Path

from sb3_maddpg.experiments.results_dir import write_json_atomic

START = re.compile(r"sweep of \d+ runs \(.*\) on (\w+) with \d+ worker\(s\) x (\d+) thread\(s\)")
"""A start of the sweep on the local backend; any other start (run groups, say) fails the check."""
SOURCE = "afterwards, from sweep.log: every start of the sweep trained runs alone on the local backend, one torch thread"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[1])
    parser.add_argument("results", type=Path, help="the sweep's results directory (holds sweep.log)")
    results = parser.parse_args().results
    starts = [line for line in (results / "sweep.log").read_text().splitlines() if "sweep of " in line]
    matches = [START.search(line) for line in starts]
    found = {(match.group(1), int(match.group(2))) if match else ("unrecognised", 0) for match in matches}
    if not starts or found != {("local", 1)}:
        raise SystemExit(
            f"sweep.log's {len(starts)} starts are not all 'on local with ... x 1 thread(s)' ({sorted(found)}): what "
            "trained the older runs cannot be told from it; leave their summaries as they are"
        )
    written = 0
    for path in sorted(results.glob("*/*/seed_*/summary.json")):
        summary = json.loads(path.read_text())
        if "torch_threads" in summary:
            continue
        summary.update(device="cpu", torch_threads=1, runs_trained_together=1, resources_recorded=SOURCE)
        write_json_atomic(path, summary)
        written += 1
    print(f"{written} summaries given what trained them ({len(starts)} starts in sweep.log, all local, 1 thread)")


if __name__ == "__main__":
    main()
