"""Facts and tools of the SAMD21/XIAO target."""
