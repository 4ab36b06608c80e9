"""Residual mirror reconstructor (Eq. 7 with the learned residual Δo_θ, trained with Eq. 9)."""
