#!/usr/bin/env bash
# An operator's session at the rig, played against the virtual rig on a pseudo-terminal
# (docs/operator.md, "A first session"): identify the rig, measure its frequency response,
# capture a drop test, identify the contact law, select the operating frequency with it, run
# there and log. Regenerates docs/figures/rig-*.{png,csv}; about a minute on 2 cores.
# On the real rig, replace the served pty by the board's port (e.g. /dev/ttyACM0).
set -euo pipefail
cargo build --release -p host-sim
h=target/release/host-sim
f=docs/figures
tmp=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null || true; rm -rf "$tmp"' EXIT

serve() { # serve SCENARIO_TOML → sets $port
    "$h" hil --serve-pty --speed 50 --scenario "$1" --out "$tmp/truth.csv" > "$tmp/server.out" &
    for _ in $(seq 100); do
        port=$(sed -n 's/^pty: //p' "$tmp/server.out")
        [ -n "$port" ] && return
        sleep 0.05
    done
    echo "the virtual rig did not start" >&2; exit 1
}

# 1. The rig as it is: its identity, and a measured frequency response at 0.0 mm.
echo "" > "$tmp/plain.toml"
serve "$tmp/plain.toml"
"$h" rig --port "$port" send id
"$h" rig --port "$port" sweep --freq-hz 2.2:4.6:0.1 \
    --out "$f/rig-sweep-wires-gap0.0.csv" --plot "$f/rig-sweep-wires-gap0.0.png"
"$h" compare --rig wires --gap-mm 0 --experiment "$f/rig-sweep-wires-gap0.0.csv" \
    --out "$f/rig-sweep-compare-wires-gap0.0.png"
kill %1; wait %1 2>/dev/null || true

# 2. A drop test (the hammer released 3 mm from the surface, 10 s into the session), the
#    contact law identified from it, and the operating frequency with that law.
printf '[[drops]]\nat_s = 10.0\nrelease_mm = 3.0\n' > "$tmp/drop.toml"
serve "$tmp/drop.toml"
"$h" rig --port "$port" capture --seconds 12 --out "$tmp/drop.csv"
"$h" identify contact --trace "$tmp/drop.csv" --mass-kg 0.298 --law spring-dashpot \
    --release-mm 3 --error profile --out "$tmp/fit.toml" --plot "$f/rig-capture-fit.png"
"$h" select --config "$tmp/fit.toml" --rig wires --gap-mm 0

# 3. Run at the rig's own target (the firmware's model) and log 30 s of tracking.
"$h" rig --port "$port" send status start
"$h" rig --port "$port" log --seconds 30 --out "$f/rig-log-wires-gap0.0.csv" \
    --plot "$f/rig-log-wires-gap0.0.png"
"$h" rig --port "$port" send stop
