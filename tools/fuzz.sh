#!/usr/bin/env bash
# Long fuzzing campaign with the harness of tests/fuzz.rs: scenes (loaded and
# rendered at 8x8, 1 spp), OBJ, PLY and PNG/JPEG/EXR textures.
#
# Each batch (one seed, CASES cases per input kind) runs in its own process
# under a memory limit (ulimit -v) and a time limit (timeout); every case
# inside must also finish within CASE_SECONDS or the harness fails it.
#
#   tools/fuzz.sh                       # 100 seeds from 1000, 200 cases per kind each
#   SEEDS=1000 START=5000 tools/fuzz.sh # more
#   DURATION=600 tools/fuzz.sh          # stop starting batches after 10 minutes
#
# Environment: BIN (an already built harness, target/release/deps/fuzz-*,
# instead of building it), START (first seed), SEEDS (number of seeds), CASES (cases per
# kind and seed), CASE_SECONDS (per case, default 10), MEM_MB (virtual memory
# per batch, default 4096), DURATION (seconds; 0 = no limit), OUT (folder for
# logs of failing batches, default $TMPDIR/snell-fuzz-logs). Inputs that fail are saved
# by the harness under $TMPDIR/snell-fuzz-failures/.
#
# Exit status: 0 when every batch passed; 1 otherwise. The summary counts
# cases per kind, and batches that failed (a panic, a non-finite pixel or a
# slow case: exit 101), crashed (abort or signal: exit >= 128) or hung
# (timeout: exit 124).
set -u
cd "$(dirname "$0")/.."

START=${START:-1000}
SEEDS=${SEEDS:-100}
CASES=${CASES:-200}
CASE_SECONDS=${CASE_SECONDS:-10}
MEM_MB=${MEM_MB:-4096}
DURATION=${DURATION:-0}
OUT=${OUT:-${TMPDIR:-/tmp}/snell-fuzz-logs}

bin=${BIN:-}
if [ -z "$bin" ]; then
    bin=$(cargo test --release --test integration --no-run 2>&1 | sed -n 's/.*Executable tests\/main.rs (\(.*\))/\1/p' | tail -n 1)
fi
if [ -z "$bin" ] || [ ! -x "$bin" ]; then
    echo "fuzz.sh: cannot build the fuzz harness (cargo test --release --test integration --no-run)" >&2
    exit 1
fi
mkdir -p "$OUT"
# A batch may take at most its cases' time plus a margin.
batch_limit=$(( CASES * CASE_SECONDS / 4 + 60 ))

declare -A cases=()
failed=0; crashed=0; hung=0; batches=0
began=$(date +%s)
for (( seed = START; seed < START + SEEDS; seed++ )); do
    if [ "$DURATION" -gt 0 ] && [ $(( $(date +%s) - began )) -ge "$DURATION" ]; then
        break
    fi
    log="$OUT/seed-$seed.log"
    (
        ulimit -v $(( MEM_MB * 1024 ))
        SNELL_FUZZ_SEED=$seed SNELL_FUZZ_CASES=$CASES SNELL_FUZZ_CASE_SECONDS=$CASE_SECONDS \
            exec timeout -k 5 "$batch_limit" "$bin" fuzz:: --test-threads 2 --nocapture
    ) >"$log" 2>&1
    status=$?
    batches=$(( batches + 1 ))
    echo "seed $seed: exit $status" >> "$OUT/progress.log"
    while read -r kind n; do
        cases[$kind]=$(( ${cases[$kind]:-0} + n ))
    done < <(sed -n 's/^fuzz \([a-z]*\): seed [0-9]*: \([0-9]*\) cases.*/\1 \2/p' "$log")
    case $status in
        0) rm -f "$log" ;;
        124|137) hung=$(( hung + 1 )); echo "seed $seed: hung (over $batch_limit s), log $log" ;;
        101) failed=$(( failed + 1 )); echo "seed $seed: failed, log $log"; grep -m3 "^fuzz .*seed.*case\|panicked" "$log" ;;
        *) crashed=$(( crashed + 1 )); echo "seed $seed: crashed (exit $status), log $log" ;;
    esac
done
elapsed=$(( $(date +%s) - began ))
echo "fuzz.sh: $batches batches (seeds $START..$(( START + batches - 1 ))) in $elapsed s"
for kind in "${!cases[@]}"; do
    echo "  $kind: ${cases[$kind]} cases"
done
echo "  failed batches (panic, non-finite pixel or case over ${CASE_SECONDS} s): $failed; crashed (abort/signal): $crashed; hung: $hung"
[ $(( failed + crashed + hung )) -eq 0 ]
