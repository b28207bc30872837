"""Baseline models (Diffusion-SDF, TMNet, LIST, InvRT) implementing radar2shape's ReconstructionModel."""

from baselines.diffusion_sdf import DiffusionSDF
from baselines.list_net import LIST
from baselines.tmnet import TMNet
