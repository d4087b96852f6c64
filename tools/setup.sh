#!/usr/bin/env bash
# One-time machine set-up for the offline build and tests: Debian packages (only
# when missing) and the project's Python virtual environment in .venv.
set -euo pipefail
cd "$(dirname "$0")/.."

have_cmd() { command -v "$1" >/dev/null 2>&1; }
have_pkg() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "install ok installed"; }
updated=0
apt_install() {
    [ $# -gt 0 ] || return 0
    if [ "$(id -u)" -ne 0 ]; then
        echo "setup: missing Debian packages: $* (install them, or run as root)" >&2
        exit 1
    fi
    export DEBIAN_FRONTEND=noninteractive
    if [ $updated -eq 0 ]; then apt-get update -qq; updated=1; fi
    echo "setup: installing $*"
    apt-get install -y -qq "$@" >/dev/null
}

need=()
have_cmd cc || need+=(gcc)
have_cmd arm-none-eabi-gcc || need+=(gcc-arm-none-eabi)
have_pkg libnewlib-arm-none-eabi || need+=(libnewlib-arm-none-eabi)
have_pkg libstdc++-arm-none-eabi-newlib || need+=(libstdc++-arm-none-eabi-newlib)   # the Arduino core is C++
have_cmd arm-none-eabi-objdump || need+=(binutils-arm-none-eabi)   # the image tier's cycle tables
have_cmd qemu-system-arm || need+=(qemu-system-arm)
have_cmd clang || need+=(clang)
have_cmd bossac || need+=(bossa-cli)   # the flash tool's uploader when PlatformIO's tool-bossac is absent (offline)
have_pkg libfaketime || need+=(libfaketime)   # flash --emulated: bossac on a clock slowed to the emulated boards' pace (LD_PRELOAD)
have_cmd valgrind || need+=(valgrind)   # the instruction counts (benchmarks/instructions.py, image_instructions.py) and their figure tests
have_cmd cmake || need+=(cmake)   # the image tier's patched Unicorn (host_emulator/image/ucbuild.py)
have_cmd patch || need+=(patch)
python3 -c 'import ensurepip' 2>/dev/null || need+=(python3-venv)
apt_install "${need[@]}"

# libFuzzer and the sanitizer runtimes matching the installed clang
if ! ls "$(clang -print-resource-dir)"/lib/linux/libclang_rt.fuzzer-x86_64.a >/dev/null 2>&1; then
    ver=$(clang -dumpversion | cut -d. -f1)
    apt_install "libclang-rt-${ver}-dev"
fi

# the sanitizer job (tests/sanitize): gcc's ASan and UBSan runtimes, which libgcc-N-dev links and brings (libasan,
# libubsan); Debian's gcc depends on it, a trimmed toolchain may not
asan=$(cc -print-file-name=libasan.so 2>/dev/null || true)
if [ "${asan#/}" = "$asan" ] || [ ! -e "$asan" ]; then
    apt_install "libgcc-$(cc -dumpversion | cut -d. -f1)-dev"
fi

if [ ! -x .venv/bin/python ]; then
    "${PYTHON:-python3}" -m venv .venv
fi
stamp=.venv/.installed-$(sha256sum pyproject.toml | cut -c1-16)
if [ ! -f "$stamp" ]; then
    .venv/bin/pip install -q --upgrade pip
    if ! .venv/bin/pip install -q -e '.[dev]' > .venv/pip.log 2>&1; then
        cat .venv/pip.log >&2
        exit 1
    fi
    rm -f .venv/.installed-*
    touch "$stamp"
fi

# the image tier's Unicorn: the pinned release's source with the project's patches, built once for ARM into
# build/unicorn/ (about a minute; nothing to do when it is built)
.venv/bin/python -m host_emulator.image.ucbuild
