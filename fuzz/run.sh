#!/bin/sh
# Run one fuzz target under nice: ./run.sh TARGET [EXECUTIONS] [extra libFuzzer flags]
# Its corpus grows in corpus/TARGET (seeded from seeds/TARGET), crashes go to
# artifacts/TARGET/. Needs cargo-fuzz (cargo install cargo-fuzz) and a nightly
# toolchain (or RUSTC_BOOTSTRAP=1 with stable).
set -e
cd "$(dirname "$0")"
t=$1
runs=${2:-10000000}
shift; [ $# -gt 0 ] && shift
case $t in
  pcc_xml) len=1048576 ;;     # room for 100 000 nested elements (issue 14)
  cine_header) len=131072 ;;  # a small whole cine (the seed is 77 kB)
  folder_frame) len=65536 ;;
  *) len=4096 ;;
esac
mkdir -p corpus/$t artifacts/$t
exec nice -n 19 cargo +nightly fuzz run "$t" corpus/$t seeds/$t -- \
  -runs="$runs" -max_len=$len -artifact_prefix=artifacts/$t/ -print_final_stats=1 "$@"
