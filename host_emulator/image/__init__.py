"""The image tier: the flashed cell and primary images run instruction by instruction against the plant."""


class ImageTierUnavailable(RuntimeError):
    """The tier cannot run here: the images cannot be built, the vendor's device headers or Unicorn are missing.
    The message says what is missing in one line."""
