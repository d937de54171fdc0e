#!/usr/bin/env bash
# Table-1 analogue of Luo et al. 2020 for `stseg`: the paper's settings on samba and
# horse-gallop under each reading of ω (§4.4 / Eq. 8), the chosen defaults, and timings with 1
# and 2 threads, with the paper's coding (`coding=paper`, stream version 2's packets). Run from the
# workspace root: `bash codec-stseg/table1.sh`.
set -euo pipefail
cargo build --release -p codec-stseg --example table1 >&2
T=target/release/examples/table1
SAMBA="samba w=5 gamma_init=15 gamma_max=50 groups=4 omega=0.99 coding=paper"
HORSE="horse-gallop w=3 gamma_init=12 gamma_max=20 groups=4 omega=0.99 coding=paper"
for data in "$SAMBA" "$HORSE"; do
  echo "### readings of ω (paper's Alg. 2: seg_centering = centering, omega_seg = omega = 0.99)"
  for c in vertex frame frame-axis none; do
    $T $data centering=$c seg_centering=$c omega_seg=0.99
  done
  echo "### defaults (frame-axis, omega_seg = 0.9), 1 thread then all threads"
  STSEG_THREADS=1 $T $data
  $T $data
done
