"""Optical (SPAD) NLOS solvers for the cross-modality comparison (Sec. 5.1.2): LCT and f-k migration."""
