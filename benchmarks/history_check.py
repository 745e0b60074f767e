"""The eight-run history check and what the gate says of the same change.

Eight runs of holweg on the simulated data at scale 0.01 (window-size at windows 50 and 100,
grouped, seeds 1 to 8: each seed also draws its own simulated dataset), ``keep`` 0.8 in runs
1-4 and 0.6 in runs 5-8, added as commits c1..c8; then ``history steps``. Beside it, the gate
on the same change: ``compare`` of runs 1-4 against runs 5-8 (refused: their datasets differ),
and ``compare`` of four seeds a side on one dataset, paired seed by seed (seeds 1-4 at keep 0.8
and at keep 0.6): the gate's best case for this change.

    python benchmarks/history_check.py [--out benchmarks/results/history_check.md]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import tempfile
from pathlib import Path

WINDOW_SIZE = ["--detector", "holweg", "--protocol", "window-size"]
SETTINGS = [*WINDOW_SIZE, "--protocol-param", "windows=[50,100]", "--split", "grouped"]
SETTINGS += ["--scale", "0.01", "--quiet"]
GATE = ["--figure", "accuracy=1", "--figure", "tn_rate=1", "--figure", "tp_rate=1"]


def slipbench(*args: str, where: Path) -> tuple[int, str]:
    done = subprocess.run(["slipbench", *args], cwd=where, capture_output=True, text=True)
    return done.returncode, (done.stdout + done.stderr).strip()


def evaluate(where: Path, out: str, seed: int, keep: float, repeats: int = 1) -> None:
    code, text = slipbench(
        "evaluate",
        *SETTINGS,
        "--seed",
        str(seed),
        "--repeats",
        str(repeats),
        "--param",
        f"keep={keep}",
        "--out",
        out,
        where=where,
    )
    if code != 0:
        raise SystemExit(f"evaluate {out} exited {code}: {text}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/history_check.md"))
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        where = Path(tmp)
        for k in range(1, 9):
            evaluate(where, f"c{k}", k, 0.8 if k <= 4 else 0.6)
            date = f"2026-01-0{k}T12:00:00Z"
            code, text = slipbench(
                "history", "add", f"c{k}", "--history", "hist", "--commit", f"c{k}",
                "--date", date, where=where,
            )  # fmt: skip
            if code != 0:
                raise SystemExit(text)
        code, steps = slipbench("history", "steps", "--history", "hist", where=where)
        apart, refused = slipbench("compare", "c1", "c5", *GATE, where=where)
        evaluate(where, "base", 1, 0.8, repeats=4)
        evaluate(where, "candidate", 1, 0.6, repeats=4)
        paired, comment = slipbench("compare", "base", "candidate", *GATE, where=where)
    load = os.getloadavg()
    text = (
        "**The eight-run history check.** "
        "Holweg on the simulated data at scale 0.01 (window-size, windows 50 and 100, grouped), "
        "seeds 1-8 (each its own simulated dataset), keep 0.8 in c1-c4 and 0.6 in c5-c8.\n\n"
        f"**`history steps`** (exit {code}):\n\n```text\n{steps}\n```\n\n"
        f"**The gate on runs of different datasets**, `compare c1 c5` (exit {apart}):\n\n"
        f"```text\n{refused}\n```\n\n"
        "**The gate's best case**: four seeds a side on one dataset, paired "
        f"(`compare base candidate`, exit {paired}):\n\n```markdown\n{comment}\n```\n\n"
        f"{os.cpu_count()} cores, load average {load[0]:.1f} at the end.\n"
    )
    args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
