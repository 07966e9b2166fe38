"""The inputs of the TF.js parity fixtures (tests/data/tfjs_parity/*.npz): each model's input
tensors from the small uint8 image its fixture stores, by the same arithmetic in the recorder
(tests/record_tfjs_parity.py) and the test (tests/test_model_runtime_parity.py).

The images are crops of assets/photos/warrior_lunge.jpg, stored at half or quarter of the
model's input side and enlarged by repeating pixels (so the fixtures stay small). Ranges follow
what Human (@vladmandic/human 3.0.4, the models' users) feeds each model: faceres RGB 0..255
float NHWC; nanodet RGB 0..1 float NCHW; movenet-thunder RGB 0..255 int32 NHWC; centernet RGB
0..255 float NHWC.
"""

from __future__ import annotations

import numpy as np

REPEAT = {"faceres": 2, "nanodet": 4, "movenet-thunder": 2, "centernet": 4}
"""How many times each stored pixel is repeated along each axis."""


def enlarged(image: np.ndarray, name: str) -> np.ndarray:
    """``image (h, w, 3) uint8`` with each pixel repeated ``REPEAT[name]`` times per axis."""
    factor = REPEAT[name]
    return np.repeat(np.repeat(image, factor, axis=0), factor, axis=1)


def model_inputs(name: str, image: np.ndarray) -> dict[str, np.ndarray]:
    """The model's inputs by placeholder name, from its fixture's stored ``image``.

    faceres: a batch of two, the face and its mirror image, ``(2, 224, 224, 3)``.
    """
    pixels = enlarged(image, name)
    if name == "faceres":
        faces = np.stack([pixels, pixels[:, ::-1]]).astype(np.float32)
        return {"input_1": np.ascontiguousarray(faces)}
    if name == "nanodet":
        scaled = pixels.astype(np.float32) / np.float32(255.0)
        return {"input_1": np.ascontiguousarray(scaled.transpose(2, 0, 1)[None])}
    if name == "movenet-thunder":
        return {"input": pixels.astype(np.int32)[None]}
    if name == "centernet":
        return {"tower_0/images": pixels.astype(np.float32)[None]}
    raise KeyError(name)
