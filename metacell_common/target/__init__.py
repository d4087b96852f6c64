"""The one home of the SAMD21/XIAO target facts used by both the emulator's image tier and fwcheck: the Cortex-M0+
cycle model and the disassembly it reads (cycles), the chip's and the cell board's figures (board), the cell board's
wiring (wiring), the PlatformIO build of each board (build), how to run PlatformIO here (pio) and the cross
binutils (toolchain)."""
