"""Flash 16 cells and the primary through PlatformIO, find boards by USB identity, verify each."""
