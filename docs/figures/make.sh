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
# The thesis' six basin points (Figs. 3.36a–3.38b: Ω/ω, gap/A0; A0 = 0.89 mm), on the undamped
# wires preset (impact / no impact, as the thesis draws them) and with the pendulum damped
# (ζ = 0.004, coloured by attractor).
for p in 2.00:2.00 2.00:1.50 1.75:2.50 1.75:3.50 2.15:1.60 2.25:1.50; do
    r=${p%%:*}
    a=${p##*:}
    g=$(awk "BEGIN { printf \"%.4f\", $a * 0.89 }")
    $h basins --rig wires --gap-mm "$g" --omega-ratio "$r" --u0-mm "-4:$g:200" \
        --v0-mm-s -100:100:200 --color-by impact \
        --out /tmp/basins.csv --plot "$f/basins-wires-ratio$r-gapA$a.png"
    $h basins --rig wires --damping-ratio 0.004 --gap-mm "$g" --omega-ratio "$r" \
        --u0-mm "-4:$g:200" --v0-mm-s -100:100:200 --max-periods 4000 \
        --out /tmp/basins.csv --plot "$f/basins-wires-z0.004-ratio$r-gapA$a.png"
done
# Basin fractions of the beam rig's hysteresis at 3.0 mm, continued over Ω/ω.
$h fractions --rig beam-170 --gap-mm 3.0 --omega-ratio 1.10:1.60:0.01 --u0-mm -6:3 \
    --v0-mm-s -300:300 --samples 2000 --max-periods 1500 \
    --out "$f/fractions-beam-170-gap3.0.csv" --plot "$f/fractions-beam-170-gap3.0.png"
$h peterka --rig wires --gap-mm 0:3.42:0.01 --freq-hz 1:7.11:0.01 --boundaries \
    --out /tmp/peterka.csv --plot "$f/peterka-wires.png" --force-plot "$f/peterka-wires-f11.png"
$h continue --rig wires --gap-mm 0 --omega-ratio 2.0 --range 1.0:3.0 --follow-doublings 2 \
    --out /tmp/continue-wires.csv --plot "$f/continue-wires-gap0.0.png"
$h continue --rig beam-170 --gap-mm 3.0 --omega-ratio 1.35 --also-at 1.7 --precision f64 \
    --range 1.0:2.0 --out /tmp/continue-beam.csv --plot "$f/continue-beam-170-gap3.0.png"
$h simulate --rig wires --gap-mm 0 --omega-ratio 2.01 --periods 6 \
    --out /tmp/simulate-wires.csv --plot "$f/simulate-wires-gap0-2.01.png"
$h orbit --rig wires --gap-mm 1.0 --omega-ratio 2.6 --q 2 \
    --out /tmp/orbit-wires.csv --plot "$f/orbit-wires-gap1.0-2.6-q2.png"
