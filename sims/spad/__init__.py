"""SPAD (optical, 850 nm) confocal NLOS forward model and transient file formats (Sec. 5.1.2)."""
