"""Mesh ray tracer: shooting-and-bouncing rays guide exact image paths (``raytrace`` forward model)."""
