"""Batched CPU/CUDA rendering of body meshes: RGB (textured, shaded), body-part labels and depth,
plus the camera, lighting, clothing-texture and background samplers used for synthetic data."""
