"""The body model: a free SMPL-format model built from Anny, and a fast linear-blend-skinning layer."""
