"""Atheris (libFuzzer for Python) on the image tier's ELF reader (elfimage.read_elf): any bytes give either load
segments the chip can hold, which is all that reaches the C loader, or one ImageError line; anything else is a
finding. Seeds in fuzz/corpus/elf/: tiny-two-segments.elf (812 bytes: a vector table and a loop linked at 0x2000,
.data programmed after it, by arm-none-eabi-as and ld -n) and its 52-byte header. Run from the repository:
python fuzz/fuzz_elf.py [libFuzzer options] [corpus]."""

import sys
from pathlib import Path

import atheris

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's packages, not an installed copy

with atheris.instrument_imports(include=["elftools", "host_emulator.image.elfimage"]):
    from host_emulator.image import elfimage

FLASH_END = 0x40000  # the SAMD21G18A's 256 KiB
NAME = Path("fuzz.elf")


def test_one_input(data: bytes) -> None:
    try:
        segments, _, _ = elfimage.read_elf(NAME, data)
    except elfimage.ImageError as e:
        assert "\n" not in str(e), str(e)
        return
    spans = sorted((s.addr, s.addr + len(s.data)) for s in segments)
    for start, end in spans:  # inside the application flash, word-aligned
        assert elfimage.APP_BASE <= start <= end <= FLASH_END and start % 4 == 0, (start, end)
    for (_, end), (start, _) in zip(spans, spans[1:]):  # and apart
        assert end <= start, spans


if __name__ == "__main__":
    atheris.Setup(sys.argv, test_one_input)
    atheris.Fuzz()
