#!/usr/bin/env bash
# Builds host-sim with profile-guided optimisation (PGO) for long grid runs: the same results bit
# for bit, 11–15 % less CPU time on the Peterka grids on an AVX2 machine (docs/performance.md,
# "A PGO build for long runs").
#
#   docs/cluster/pgo-build.sh        # from anywhere in the workspace; about 15 minutes on 2 cores
#
# It uses cargo-pgo 0.3 (installed with `cargo install cargo-pgo --locked` if missing) and the
# toolchain's llvm-tools (added with rustup if missing): an instrumented build, a training run
# (the commands below: a Peterka grid on each suspension, a basin, the main job), the optimised
# build, then a check that the optimised binary writes the training grid's CSV byte for byte.
# Prints only the binary's path on stdout (all else on stderr): HOST_SIM=$(docs/cluster/pgo-build.sh).
set -euo pipefail

cd "$(dirname "$0")/../.."
triple=$(rustc -vV | sed -n 's/^host: //p')
bin="target/$triple/release/host-sim"

if ! cargo pgo --version >/dev/null 2>&1; then
    echo "pgo-build: installing cargo-pgo (cargo install cargo-pgo --version ^0.3 --locked)" >&2
    cargo install cargo-pgo --version '^0.3' --locked >&2
fi
# The llvm-profdata of the pinned toolchain (rust-toolchain.toml), which reads its rustc's profiles.
rustup component add llvm-tools >/dev/null

# The grid trained on and compared: every 49th gap of the thesis' map (4,284 points).
grid=(peterka --rig wires --gap-mm 0:2.94:0.49 --freq-hz 1:7.11:0.01)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

cargo pgo clean >&2
echo "pgo-build: instrumented build" >&2
cargo pgo build -- -p host-sim >&2

echo "pgo-build: training run" >&2
export LLVM_PROFILE_FILE="$PWD/target/pgo-profiles/host-sim_%m_%p.profraw"
"$bin" "${grid[@]}" --out "$work/wires.csv" >/dev/null
"$bin" peterka --rig beam-150 --gap-mm 0:3:0.5 --freq-hz 1:12:0.05 --out "$work/beam.csv" >/dev/null
"$bin" basins --rig wires --gap-mm 0 --omega-ratio 2 --u0-mm -2:0:40 --v0-mm-s -20:20:40 \
    --out "$work/basin.csv" >/dev/null
"$bin" select --rig wires --gap-mm 0 >/dev/null
unset LLVM_PROFILE_FILE

echo "pgo-build: optimised build" >&2
cargo pgo optimize build -- -p host-sim >&2

# The same source with and without instrumentation: the same bits.
"$bin" "${grid[@]}" --out "$work/check.csv" >/dev/null
if ! cmp -s "$work/wires.csv" "$work/check.csv"; then
    echo "pgo-build: the optimised binary's grid differs from the instrumented one's: do not use $bin" >&2
    exit 1
fi
echo "pgo-build: the optimised grid is byte-identical to the instrumented one's" >&2
echo "$PWD/$bin"
