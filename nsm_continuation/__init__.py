"""nsm_continuation: continuation of nonsmooth modes of vibration of impacting systems."""

__version__ = "0.1.0"
