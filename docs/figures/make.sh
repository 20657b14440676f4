#!/usr/bin/env bash
# Regenerates the committed analysis figures (docs/analysis.md and the README): about 5 minutes
# on 2 cores. Run from the repository root. The virtual rig's and the identification's figures
# have their own commands (docs/virtual-rig.md, docs/operator.md, docs/identification.md).
set -euo pipefail
cargo build --release -p host-sim
h=target/release/host-sim
f=docs/figures
for g in 0 1.0 2.4; do
    n=$(printf '%.1f' "$g")
    $h response --rig wires --gap-mm "$g" --omega-ratio 0.5:5.0:0.01 \
        --out "$f/response-wires-gap$n.csv" --plot "$f/response-wires-gap$n.png"
    $h bifurcation --rig wires --gap-mm "$g" --omega-ratio 0.5:4.0:0.005 \
        --out /tmp/bifurcation-wires-gap$n.csv --plot "$f/bifurcation-wires-gap$n.png"
done
$h bifurcation --rig beam-170 --gap-mm 3.0 --omega-ratio 0.5:3.0:0.005 --continuation both \
    --out /tmp/bifurcation-beam-170.csv --plot "$f/bifurcation-beam-170-gap3.0-continuation.png"
$h select --rig wires --gap-mm 0 --out "$f/select-wires-gap0.csv" --plot "$f/select-wires-gap0.png"
$h select --rig beam-170 --gap-mm 0 --out "$f/select-beam-170-gap0.csv" --plot "$f/select-beam-170-gap0.png"
$h basins --rig wires --gap-mm 1.335 --omega-ratio 2.0 --u0-mm -4:1.335:200 --v0-mm-s -100:100:200 \
    --out /tmp/basins.csv --plot "$f/basins-wires-ratio2.00-gapA1.50.png"
$h peterka --rig wires --gap-mm 0:3.42:0.01 --freq-hz 1:7.11:0.01 --boundaries \
    --out /tmp/peterka.csv --plot "$f/peterka-wires.png" --force-plot "$f/peterka-wires-f11.png"
$h continue --rig wires --gap-mm 0 --omega-ratio 2.0 --range 1.0:3.0 --follow-doublings 2 \
    --out /tmp/continue-wires.csv --plot "$f/continue-wires-gap0.0.png"
$h continue --rig beam-170 --gap-mm 3.0 --omega-ratio 1.35 --also-at 1.7 --precision f64 \
    --range 1.0:2.0 --out /tmp/continue-beam.csv --plot "$f/continue-beam-170-gap3.0.png"
$h simulate --rig wires --gap-mm 0 --omega-ratio 2.01 --periods 6 \
    --out /tmp/simulate-wires.csv --plot "$f/simulate-wires-gap0-2.01.png"
