"""Baseline models (Diffusion-SDF, TMNet, LIST, InvRT) implementing radar2shape's ReconstructionModel."""
