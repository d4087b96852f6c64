"""pytest plugin of the sanitized run (test_sanitizers.py passes it with -p): one sanitized build serves both tiers.

The image tier's runtime compiles the firmware library and host_emulator/csrc with its own sources and declares all
of their functions, so the host tier's tests run on it too: firmware.load returns it, and the run builds one
sanitized module instead of two."""

from __future__ import annotations


def pytest_configure(config) -> None:
    import metacell_common.firmware as common
    from host_emulator import firmware
    from host_emulator.image import runtime

    if not common.SANITIZE:
        raise RuntimeError("the sanitized run needs MC_SANITIZE=1 (and the ASan runtime preloaded)")

    def load():
        return runtime.load()

    common.load = load
    firmware.load = load
