"""From a photo to a body posterior: image loading, 2D keypoint detection, cropping, the
`Predictor` and the `hkpd-predict` command."""
