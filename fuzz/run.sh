#!/bin/sh
# Run one fuzz target under nice: ./run.sh TARGET [EXECUTIONS] [extra libFuzzer flags]
# Its corpus grows in corpus/TARGET (seeded from seeds/TARGET), crashes go to
# artifacts/TARGET/. Needs cargo-fuzz (cargo install cargo-fuzz) and a nightly
# toolchain (or RUSTC_BOOTSTRAP=1 with stable).
#
# Built optimised with debug assertions (integer overflow checks, `debug_assert!`)
# and without AddressSanitizer (-s none): on the fuzzed paths dropscope is
# safe Rust (its one `unsafe` there is a prefetch hint), and ASan slowed the
# targets several times over (docs/input.md, Fuzzing). For an ASan run, replace
# `-s none` by `-s address` below.
set -e
cd "$(dirname "$0")"
t=$1
runs=${2:-10000000}
shift; [ $# -gt 0 ] && shift
case $t in
  pcc_xml) len=1048576 ;;     # room for 100 000 nested elements
  cine_header) len=32768 ;;   # the seeds are small whole cines of 11 kB
  photron) len=32768 ;;       # a .cihx is 5–60 kB; the seeds are 1–2 kB
  folder_frame) len=65536 ;;
  *) len=4096 ;;
esac
# track_events: a shaped drop's damage needs inputs longer than libFuzzer's
# slowly growing length limit allows early on (34 bytes after 12 minutes).
case $t in
  track_events) set -- -len_control=0 "$@" ;;
esac
mkdir -p corpus/$t artifacts/$t
exec nice -n 19 cargo +nightly fuzz run -O -a -s none "$t" corpus/$t seeds/$t -- \
  -runs="$runs" -max_len=$len -artifact_prefix=artifacts/$t/ -print_final_stats=1 "$@"
