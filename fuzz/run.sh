#!/usr/bin/env bash
# Build the libFuzzer harnesses (clang, ASan + UBSan) and run the Atheris ones, fuzz each for N seconds, merge new
# finds into fuzz/corpus/.
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-60}
out=build/fuzz
mkdir -p "$out"
srcs=$(find lib/metacell/src -name '*.c' | sort)
for h in slcan regs; do
    clang -g -O1 -std=c99 -pedantic -Wall -Wextra -Werror -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined \
        -Ilib/metacell/src "fuzz/fuzz_$h.c" $srcs -o "$out/fuzz_$h"
    mkdir -p "$out/new_$h"
    (cd "$out" && "./fuzz_$h" -max_total_time="$secs" -timeout=5 "new_$h" "../../fuzz/corpus/$h")
    "$out/fuzz_$h" -merge=1 "fuzz/corpus/$h" "$out/new_$h"
done
# the Atheris (Python) targets: the image tier's ELF reader and the scene parser
for h in elf scene; do
    mkdir -p "$out/new_$h"
    (cd "$out" && ../../.venv/bin/python "../../fuzz/fuzz_$h.py" -max_total_time="$secs" -timeout=10 "new_$h" "../../fuzz/corpus/$h")
    .venv/bin/python "fuzz/fuzz_$h.py" -merge=1 "fuzz/corpus/$h" "$out/new_$h"
done
