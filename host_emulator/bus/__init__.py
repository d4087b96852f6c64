"""The emulated data path: compiled cell register handlers and primary scheduler over an I2C timing model, served as
SLCAN on a pty."""
