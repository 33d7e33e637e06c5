#!/usr/bin/env bash
# Do two builds of dropscope write the same outputs? Runs both on the same
# inputs and compares the output folders byte for byte.
#
#   tools/same-outputs.sh A B [WORK]
#
# A and B are dropscope binaries, or git revisions of this repository (each
# built with `cargo build --release` in a temporary worktree, into
# $CARGO_TARGET_DIR or that worktree's target/). WORK (default: a new
# temporary folder) receives the outputs, kept for a look after a
# difference.
#
# What is run, by each binary:
#   1. the main job on this checkout's pipeline.toml (the fixtures):
#        dropscope --config pipeline.toml --out WORK/run/main --threads 2
#   2. a rendered campaign, rendered by each binary (the two renders are
#      compared too), then the one rendered by A processed by both, so that
#      both read the same files (an input's modification time is part of
#      what a job records):
#        dropscope render --campaign --preset realistic --repeats 1 --seed 5 \
#            --scaled-manifest --out WORK/run/campaign
#        dropscope process --manifest WORK/input/campaign/runs_scaled.csv \
#            --out WORK/run/processed --threads 2
#        dropscope collapse WORK/run/processed/drops.csv --out WORK/run/processed
#   Each binary writes into the same paths (WORK/run/..., moved to WORK/A/
#   or WORK/B/ after), so that no path in an output differs.
#
# Every file is compared byte for byte, except the two kinds that record
# which build made them: `dropscope_source_sha256` (the SHA-256 of the
# sources a binary was built from, see build.rs) and the cache keys hashed
# over it. They are compared with those fields masked:
#   provenance.json   `dropscope_source_sha256`, and each run's `key`
#   runs/<run>.json   (each run's cache entry) `key`, `scene_key`, and
#                     `entry_sha256`, the hash that seals the entry
# Standard output and error of each command (WORK/X/logs/) are compared as
# well, with the times and rates of the progress and summary lines masked
# and the lines sorted (runs finish in any order, counted `[k/N]` as they
# finish).
#
# Exit status: 0 identical, 1 some file differs, 2 could not run.

set -euo pipefail

if [[ $# -lt 2 || $# -gt 3 ]]; then
    sed -n '2,/^$/p' "$0" | sed 's/^# \{0,1\}//'
    exit 2
fi

repo=$(cd "$(dirname "$0")/.." && pwd)
work=${3:-$(mktemp -d "${TMPDIR:-/tmp}/same-outputs.XXXXXX")}
mkdir -p "$work"
echo "outputs in $work"

# A binary: the path as given, or a git revision built in a temporary worktree.
binary() {
    local what=$1 name=$2
    if [[ -f $what && -x $what ]]; then
        realpath "$what"
        return
    fi
    local rev
    rev=$(git -C "$repo" rev-parse --verify "$what^{commit}" 2>/dev/null) || {
        echo "same-outputs: $what is neither an executable nor a git revision" >&2
        exit 2
    }
    local tree="$work/src-$name"
    rm -rf "$tree"
    git -C "$repo" worktree add --detach --quiet "$tree" "$rev" >&2
    local target=${CARGO_TARGET_DIR:-$tree/target}
    (cd "$tree" && CARGO_TARGET_DIR=$target nice -n 10 cargo build --release --quiet >&2)
    cp "$target/release/dropscope" "$work/dropscope-$name"
    git -C "$repo" worktree remove --force "$tree" >&2
    echo "$work/dropscope-$name"
}

bin_a=$(binary "$1" A)
bin_b=$(binary "$2" B)
echo "A: $bin_a"
echo "B: $bin_b"

# Run one command of one binary in the repository, its output kept in
# WORK/X/logs/NAME. Every command writes to WORK/run/NAME, moved to
# WORK/X/NAME after it: both binaries see the same paths.
run() {
    local x=$1 name=$2
    shift 2
    local bin
    if [[ $x == A ]]; then bin=$bin_a; else bin=$bin_b; fi
    mkdir -p "$work/$x/logs"
    local status=0
    (cd "$repo" && "$bin" "$@") >"$work/$x/logs/$name.out" 2>"$work/$x/logs/$name.err" || status=$?
    echo "$status" >"$work/$x/logs/$name.status"
}

keep() {
    local x=$1 name=$2
    if [[ -e "$work/run/$name" ]]; then
        mv "$work/run/$name" "$work/$x/$name"
    fi
}

rm -rf "${work:?}/A" "${work:?}/B" "${work:?}/run" "${work:?}/input"
mkdir -p "$work/run" "$work/input"
for x in A B; do
    echo "$x: the main job on pipeline.toml"
    run "$x" main --config "$repo/pipeline.toml" --out "$work/run/main" --threads 2
    keep "$x" main
    echo "$x: render the campaign"
    run "$x" render render --campaign --preset realistic --repeats 1 --seed 5 \
        --scaled-manifest --out "$work/run/campaign"
    keep "$x" campaign
done
cp -a "$work/A/campaign" "$work/input/campaign"
for x in A B; do
    echo "$x: process and collapse the campaign rendered by A"
    run "$x" process process --manifest "$work/input/campaign/runs_scaled.csv" \
        --out "$work/run/processed" --threads 2
    run "$x" collapse collapse "$work/run/processed/drops.csv" --out "$work/run/processed"
    keep "$x" processed
done

# Masks what legitimately differs between two builds (see the top).
normalise() {
    local rel=$1 file=$2
    case $rel in
        provenance.json | */provenance.json | runs/*.json | */runs/*.json)
            sed -E 's/("(dropscope_source_sha256|key|scene_key|entry_sha256)": *)"[0-9a-f]{64}"/\1"(masked)"/' "$file"
            ;;
        logs/*)
            # Each finished run, and each job's summary, says how long it
            # took; runs finish in any order, counted as they finish.
            sed -E -e 's#[0-9]+(\.[0-9]+)? frames/s#(rate)#g' -e 's#^\[[0-9]+/#[k/#' \
                -e 's/[0-9]+(\.[0-9]+)? ?(ms|s|min|µs)\b/(time)/g' "$file" | sort
            ;;
        *)
            cat "$file"
            ;;
    esac
}

# Compare every file of A's outputs with B's.
differ=0
files=0
masked=0
while IFS= read -r -d '' f; do
    rel=${f#"$work/A/"}
    files=$((files + 1))
    other="$work/B/$rel"
    if [[ ! -e $other ]]; then
        echo "only in A: $rel"
        differ=1
        continue
    fi
    if cmp -s "$f" "$other"; then
        continue
    fi
    if cmp -s <(normalise "$rel" "$f") <(normalise "$rel" "$other"); then
        masked=$((masked + 1))
        continue
    fi
    echo "DIFFERS: $rel"
    differ=1
done < <(find "$work/A" -type f -print0 | sort -z)
while IFS= read -r -d '' f; do
    rel=${f#"$work/B/"}
    if [[ ! -e "$work/A/$rel" ]]; then
        echo "only in B: $rel"
        differ=1
    fi
done < <(find "$work/B" -type f -print0 | sort -z)

for x in A B; do
    for s in "$work/$x"/logs/*.status; do
        if [[ $(cat "$s") != 0 ]]; then
            echo "note: $x's $(basename "$s" .status) exited with status $(cat "$s")"
        fi
    done
done

if [[ $differ == 0 ]]; then
    echo "IDENTICAL: $files files (of which $masked equal once the build's source hash is masked)"
    exit 0
fi
echo "DIFFERENT (outputs kept in $work)"
exit 1
