#!/usr/bin/env bash
# Regenerate reports/: the paper's tables and figures reproduced on the simulated default dataset.
#
#   reports/reproduce.sh                      # every protocol with every built-in detector (~15 min on 2 cores)
#   DETECTORS="holweg lstm" reports/reproduce.sh   # a subset
#
# Results go to $RESULTS (default build/reproduction); finished cells are reused on a rerun.
set -euo pipefail
cd "$(dirname "$0")/.."
RESULTS=${RESULTS:-build/reproduction}
DETECTORS=${DETECTORS:-all}
for detector in $DETECTORS; do
  echo "evaluate $detector x all protocols" >&2
  slipbench evaluate --detector "$detector" --protocol all --jobs 2 --out "$RESULTS" --quiet > /dev/null
done
rm -rf reports/figures
slipbench report "$RESULTS" --paper --intervals --plots reports/figures --out "$RESULTS/tables.md" > /dev/null
slipbench report "$RESULTS" --format latex --standalone --out reports/tables.tex > /dev/null
{
  cat <<'TEXT'
# The paper reproduced, on simulated data

**The data behind every number here is simulated.** The recordings of Van Wyk & Falco are not
public; slipbench's default dataset is a physical simulation of their design of experiments
(three sensor types, eight units, five materials, four slip speeds, pressing and free-space
motion; see `datasets.md`). The simulation is not tuned to the paper's numbers, so agreement
or disagreement with the published tables says how the *method* behaves on such data, not how
these sensors behave.

Each table shows our result with its 95 % interval (bootstrap over recordings), then the
published table (the paper's LSTM) and the difference in accuracy points. Figures are in
`figures/` (PNG and PDF); the same tables in LaTeX are in `tables.tex`.

Regenerate everything with one command from the repository root:

```bash
reports/reproduce.sh
```

TEXT
  echo "Dataset fingerprint(s): $(python -c "import pandas as pd, sys; print(', '.join(sorted(pd.read_parquet(sys.argv[1])['dataset_fingerprint'].unique())))" "$RESULTS/results.parquet"); slipbench $(python -c 'import slipbench; print(slipbench.__version__)')."
  echo
  cat "$RESULTS/tables.md"
  echo
  echo "## Figures"
  for png in reports/figures/*.png; do echo; echo "![$(basename "$png" .png)](figures/$(basename "$png"))"; done
} > reports/README.md
echo "wrote reports/README.md, reports/tables.tex and reports/figures/" >&2
