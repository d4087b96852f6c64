"""The researcher's workbench around the emulator: the Python API (api), one dataset for every run (datasets),
sweeps on Dask (sweep) and their batched runner (batch), the paper's figures (paper) and their robustness
(robustness), plots, live trackers and animations. The package's top level (``import host_emulator as he``)
exposes the functions; the modules here hold them."""
