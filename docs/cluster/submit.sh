#!/bin/bash
# Submits a grid as a SLURM job array of N shards and its merge, which waits for every task:
#
#   docs/cluster/submit.sh peterka 16 run1 --rig wires --gap-mm 0:3.42:0.01 --freq-hz 1:7.11:0.01
#   docs/cluster/submit.sh basins 8 run2 --rig wires --gap-mm 1.335 --omega-ratio 2.0 \
#       --u0-mm -4:1.335:200 --v0-mm-s -100:100:200
#   docs/cluster/submit.sh fractions 8 run3 --rig beam-170 --gap-mm 3.0 --omega-ratio 1.1:1.6:0.01
#   docs/cluster/submit.sh bifurcation 4 run4 --rig wires --gap-mm 0 --omega-ratio 0.5:5:0.001
#
# Writes RUN/shards/KIND_i.csv, then RUN/KIND.csv and its figures (with peterka's --boundaries,
# RUN/peterka-boundaries.csv too); logs in RUN/logs. Prints the
# two job ids (`array ID merge ID`). HOST_SIM overrides the host-sim binary (default: on PATH);
# use the same binary for every task and the merge (its version is part of the shards' metadata).
# A failed task: resubmit just its index and the merge with the line this prints. RUN_DIR must
# be new (no shards or results of an earlier run) and without a comma.
set -euo pipefail
if [ $# -lt 3 ]; then
    echo "usage: $0 peterka|basins|fractions|bifurcation SHARDS RUN_DIR GRID_OPTIONS..." >&2
    exit 2
fi
kind=$1 n=$2 run=$3
shift 3
case "$kind" in
    peterka | basins | fractions | bifurcation) ;;
    *) echo "KIND must be peterka, basins, fractions or bifurcation" >&2; exit 2 ;;
esac
[[ "$n" =~ ^[1-9][0-9]*$ ]] || { echo "SHARDS must be a positive whole number" >&2; exit 2; }
# The scripts name every output: an output option among the grid's would make every task fail
# once it starts, after its wait in the queue.
boundaries=0
for a in "$@"; do
    case "$a" in
        --out | --out=* | --plot | --plot=* | --force-plot | --force-plot=* | --boundaries-out | \
            --boundaries-out=* | --attractors-out | --attractors-out=* | --shard | --shard=*)
            echo "${a%%=*}: the scripts write RUN_DIR/shards/${kind}_i.csv and the merge's RUN_DIR/$kind.* (and --shard is the array's): leave it out of GRID_OPTIONS" >&2
            exit 2
            ;;
        --continuation | --continuation=*)
            echo "--continuation: a continuation is sequential along the sweep and cannot be sharded; run it as one job" >&2
            exit 2
            ;;
        --boundaries) boundaries=1 ;;
    esac
done
here=$(cd "$(dirname "$0")" && pwd)
case "$run" in *,*) echo "RUN_DIR must not contain a comma (sbatch --export splits at commas): $run" >&2; exit 2 ;; esac
mkdir -p "$run/logs"
run=$(cd "$run" && pwd)
# sbatch --export splits its list at commas: the folder would be cut there.
case "$run" in *,*) echo "RUN_DIR must not contain a comma (sbatch --export splits at commas): $run" >&2; exit 2 ;; esac
# Shards or results of an earlier run would be merged with this one's, or stand as its results.
if compgen -G "$run/shards/*.csv" >/dev/null || [ -e "$run/$kind.csv" ]; then
    echo "$run holds shards or results of an earlier run: give a new RUN_DIR, or remove $run/shards and $run/$kind.*" >&2
    exit 2
fi
common=(--export="ALL,KIND=$kind,N=$n,OUTDIR=$run,BOUNDARIES=$boundaries")
array=$(sbatch --parsable "${common[@]}" --array="0-$((n - 1))" \
    --output="$run/logs/${kind}_%A_%a.out" "$here/grid-array.sbatch" "$@")
merge=$(sbatch --parsable "${common[@]}" --dependency="afterok:$array" \
    --output="$run/logs/${kind}_merge_%j.out" "$here/grid-merge.sbatch")
echo "array $array merge $merge"
# The lines that rerun task I and then the merge, quoted to be pasted as they are.
env=${HOST_SIM:+HOST_SIM=$(printf '%q' "$HOST_SIM") }
rerun="sbatch --parsable $(printf '%q ' "${common[@]}")--array=I $(printf '%q ' "--output=$run/logs/${kind}_%A_%a.out" "$here/grid-array.sbatch" "$@")"
remerge="sbatch $(printf '%q ' "${common[@]}")--dependency=afterok:\$id $(printf '%q ' "--output=$run/logs/${kind}_merge_%j.out" "$here/grid-merge.sbatch")"
echo "to rerun task I (replace I), then the merge once it has run:" >&2
echo "  id=\$(${env}${rerun% }) && ${env}${remerge% }" >&2
