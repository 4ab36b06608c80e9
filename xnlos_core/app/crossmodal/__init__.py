"""The cross-modality study: X-band radar against SPAD (and 77 GHz) at matched power, one config."""
