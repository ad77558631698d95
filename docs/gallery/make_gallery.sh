#!/usr/bin/env bash
# Regenerates docs/gallery/*.png with `frbench terrain show` (Go2, seed 0): seven families x levels 1, 5, 10.
set -euo pipefail
cd "$(dirname "$0")"
for family in flat rough slopes stairs stones gaps beams; do
  for level in 1 5 10; do
    frbench terrain show "$family" --level "$level" --seed 0 --size 400x300 --out "${family}-${level}.png"
  done
done
