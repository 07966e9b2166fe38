"""The teaching tab: the selected joint's concentrations, the proxy representation the network
saw, the person mask and what the body's shape rests on, and a short explanation of what is on
screen."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import torch
import viser

from hkpd.coco_keypoints import COCO17_NAMES
from hkpd.explorer.panels.actions import StateActions
from hkpd.kinematic_tree import BODY_JOINT_NAMES

AXIS_NAMES = ("red", "green", "blue")
"""The principal axes' arrow colours in the scene, in order."""

NETWORK_COLUMN_NOTE = """

*network (sorted)*: the network's own concentrations for this joint, before conditioning on
the keypoints, smallest first. Its principal axes are not the conditioned ones (the fit turns
them), so its numbers are listed in order of size rather than beside an arrow. Conditioning
re-centres the distribution and takes the curvature at the new most likely pose, so a number
can be lower than the network's (see *What am I looking at?*)."""

EXPLANATION = """\
**What you are looking at.** The photo (left) goes through the network, which predicts a
*probability distribution* over 3D bodies, not one body. By default that distribution is then
*conditioned on the 2D keypoints* the detector found (the dots on the photo: green where the
detector is confident, red where it is not): the network's distribution is the prior, the
keypoints are the evidence. The solid body is the most likely one (the mode); the ghosts are
samples from the distribution; the orange and blue lines on the photo are the mode's and the
samples' skeletons projected back onto it. The body on the right is coloured by how far its
vertices move across the samples (dark purple: certain, yellow: uncertain; log scale, the
colour bar gives centimetres). *Colouring: Change* shows instead each vertex's uncertainty
divided by its uncertainty on the same photo without occluders and with default
concentrations (grey: unchanged, red: more uncertain, blue: less).

**Try it.** Shift + drag on the photo to hide part of the person behind a box: the keypoints
under it stop counting as evidence, the joints that moved the hidden part fall back to the
network's (wider) prior, and their limb spreads out and turns red in the change colouring.
Untick *Condition on 2D keypoints* to see the network alone. The sliders scale each joint's
*concentration* by hand (their labels show the factor).

**The maths.** Each joint's rotation relative to its parent follows a matrix-Fisher
distribution with parameter F = U S V&#x1D40;. The arrows at the selected joint are its principal
axes; the numbers are the concentrations s&#x2C7C; + s&#x2096; for rotations about each axis:
large means confident. Conditioning does not simply add the keypoints' evidence to the
network's F: the fit moves the most likely pose to where the network's prior and the keypoints
agree best, and the conditioned concentrations are the curvature of that combined log-density
at the new mode (a Laplace approximation). Where the new mode sits away from the network's, on
the flank of its prior, the prior's curvature there is smaller than at its peak, so a
conditioned concentration can be LOWER than the network's about some axes (the table above
shows both).
"""


MASK_COLOUR = np.array([70.0, 140.0, 255.0])
"""The person mask's colour over the edges in the *Person mask* image (RGB)."""

UNKNOWN_COLOUR = np.array([110.0, 110.0, 110.0])
"""Where the photo says nothing (occluders, outside the photo) in the *Person mask* image."""

MODE_OUTLINE_COLOUR = np.array([255.0, 90.0, 60.0])
"""The most likely body's outline over the mask in the *Person mask* image (RGB)."""


def person_mask_image(
    mask: np.ndarray,
    known: np.ndarray,
    edges: np.ndarray | None = None,
    mode: np.ndarray | None = None,
) -> np.ndarray:
    """The *Person mask* picture: BlazePose's person probability in blue over the (dimmed) edge
    image, grey where the photo says nothing, and the most likely body's outline in red.

    Args:
        mask: ``(S, S)`` float person probability in [0, 1], crop pixels.
        known: ``(S, S)`` bool, where the photo shows body or background.
        edges: ``(S, S)`` float edge image in [0, 1] (None: black).
        mode: ``(S, S)`` bool, the mode body's pixels in the same crop (None: no outline).

    Returns:
        ``(S, S, 3)`` uint8 RGB.
    """
    base = np.zeros((*mask.shape, 3)) if edges is None else edges[..., None] * 90.0 * np.ones(3)
    probability = np.clip(mask, 0.0, 1.0)[..., None]
    picture = base * (1 - probability) + MASK_COLOUR * probability
    picture = np.where(known[..., None], picture, UNKNOWN_COLOUR)
    if mode is not None:
        picture[outline(mode)] = MODE_OUTLINE_COLOUR
    return np.clip(picture, 0, 255).astype(np.uint8)


def outline(region: np.ndarray) -> np.ndarray:
    """``(S, S)`` bool: the pixels of ``region`` with a 4-neighbour outside it (or the edge)."""
    cross = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
    inner = cv2.erode(region.astype(np.uint8), cross, borderType=cv2.BORDER_CONSTANT, borderValue=0)
    return region & ~inner.astype(bool)


def mode_in_crop(overlay_rgba: np.ndarray, size: int) -> np.ndarray:
    """``(size, size)`` bool: the mode's pixels from its overlay render over the crop box
    (``(R, R, 4)`` uint8, :class:`hkpd.prediction.exports.fit_overlay.FitOverlay`'s ``rgba``),
    resampled to the crop's pixels (covered at least half)."""
    alpha = overlay_rgba[..., 3].astype(np.float32) / 255.0
    return cv2.resize(alpha, (size, size), interpolation=cv2.INTER_AREA) >= 0.5


def mask_iou(mode: np.ndarray, mask: np.ndarray, known: np.ndarray) -> float:
    """IoU of the mode's pixels and the mask at probability 0.5, over known pixels."""
    person = (mask >= 0.5) & known
    body = mode & known
    union = int((person | body).sum())
    return float((person & body).sum() / union) if union else 0.0


def shape_basis_text(has_mask: bool, reads_mask: bool, fit_terms: tuple[str, ...]) -> str:
    """What the body's shape rests on, in a sentence or two (markdown).

    Args:
        has_mask: the detector gave a person mask for this photo.
        reads_mask: the network's input includes the mask (an ``"edges+mask"`` network).
        fit_terms: the evidence terms the conditioning fit weighed (empty: the network alone).
    """
    sources = ["the network's reading of the edges and keypoints"]
    if reads_mask and has_mask:
        sources[0] = "the network's reading of the edges, keypoints and person mask"
    if "silhouette" in fit_terms:
        sources.append("the person mask in the fit (silhouette evidence)")
    elif fit_terms:
        sources.append("the keypoints in the fit (they carry almost no shape)")
    text = "**What the shape rests on:** " + " and ".join(sources) + "."
    if not has_mask:
        return text + " No person mask was found for this photo."
    if "silhouette" not in fit_terms and not reads_mask:
        text += (
            " The mask (below) is not used for the shape: the shipped model returns close to the "
            "average body. Tick *Fit the person mask* (Photo tab) to fit the body's outline to "
            "it (docs/shape.md)."
        )
    elif "silhouette" in fit_terms:
        text += (
            " The outline follows the mask where the photo shows the person; girth and height "
            "move most, the finer coefficients hardly (one view holds little of them)."
        )
    return text


NUM_KEYPOINTS = len(COCO17_NAMES)
"""The proxy's last channels: one heatmap per COCO-17 keypoint."""

JOINT_LABELS = tuple(name.replace("_", " ") for name in BODY_JOINT_NAMES)
"""The Joint menu's entries ("left elbow"), in :data:`BODY_JOINT_NAMES` order."""


def joint_label(name: str) -> str:
    """The Joint menu's entry of a body-joint name (``left_elbow`` -> ``left elbow``)."""
    return JOINT_LABELS[BODY_JOINT_NAMES.index(name)]


def joint_name(label: str) -> str:
    """The body-joint name of a Joint menu entry (``left elbow`` -> ``left_elbow``)."""
    return BODY_JOINT_NAMES[JOINT_LABELS.index(label)]


@dataclass(frozen=True)
class TeachingSection:
    """Handles of the teaching folder.

    Attributes:
        joint: the joint whose principal axes are shown.
        axes_text: its concentrations as a table.
        proxy_edges: the edge image the network saw.
        proxy_heat: the 17 joint heatmaps over the edges.
        shape_text: what the body's shape rests on.
        person_mask: BlazePose's person mask in the crop (hidden without one).
    """

    joint: viser.GuiDropdownHandle[str]
    axes_text: viser.GuiMarkdownHandle
    proxy_edges: viser.GuiImageHandle
    proxy_heat: viser.GuiImageHandle
    shape_text: viser.GuiMarkdownHandle
    person_mask: viser.GuiImageHandle

    def show_teaching(
        self,
        joint: str,
        concentrations: np.ndarray,
        factor: float,
        prior_concentrations: np.ndarray | torch.Tensor | None = None,
    ) -> None:
        """Numbers for the selected joint's principal axes (and the network's own, when the
        distribution is conditioned on the keypoints, so a class sees what the evidence adds).

        Args:
            joint: the joint's name.
            concentrations: ``(3,)`` s_j + s_k about each principal axis, after the factor.
            factor: the joint's concentration factor.
            prior_concentrations: ``(3,)`` the network's own (same factor), or None.
        """
        title = f"**{joint.replace('_', ' ')}** (factor {factor:.2g}×): concentration "
        title += "s&#x2C7C; + s&#x2096; about each principal axis"
        note = ""
        if prior_concentrations is None:
            header = "| axis | concentration |\n|---|---|"
            columns = [concentrations]
        else:
            header = "| axis | with evidence | network (sorted) |\n|---|---|---|"
            columns = [concentrations, sorted(np.asarray(prior_concentrations, float).tolist())]
            note = NETWORK_COLUMN_NOTE
        rows = [
            "| " + " | ".join([name, *(f"{float(value):,.1f}" for value in values)]) + " |"
            for name, *values in zip(AXIS_NAMES, *columns, strict=True)
        ]
        self.axes_text.content = f"{title}\n\n{header}\n" + "\n".join(rows) + note

    def show_proxy(self, proxy: torch.Tensor | None) -> None:
        """The proxy representation the network saw (``(C + 17, S, S)``: the edge image, an
        ``"edges+mask"`` network's mask plane, then the 17 joint heatmaps), or nothing when the
        provider has none."""
        self.proxy_edges.visible = self.proxy_heat.visible = proxy is not None
        if proxy is None:
            return
        array = proxy.detach().float().cpu().numpy()
        edges = (np.clip(array[0], 0, 1) * 255).astype(np.uint8)
        self.proxy_edges.image = np.repeat(edges[:, :, None], 3, axis=2)
        heat = np.clip(array[-NUM_KEYPOINTS:].max(axis=0), 0, 1)
        colour = np.stack([heat * 255, heat * 170, 40 + heat * 0], axis=-1)
        background = np.repeat(edges[:, :, None] * 0.35, 3, axis=2)
        self.proxy_heat.image = np.clip(np.maximum(colour, background), 0, 255).astype(np.uint8)

    def show_shape_basis(
        self,
        posterior: object,
        proxy: torch.Tensor | None,
        overlay_rgba: np.ndarray | None = None,
    ) -> None:
        """The person mask and what the shape rests on, for ``posterior`` (a
        :class:`hkpd.prediction.BodyPosterior`; a custom provider's posterior without a network
        input shows only the sentence). ``overlay_rgba``: the mode's render over the crop box
        (the app's fit overlay): its outline is drawn on the mask and its IoU with the mask
        said."""
        network_input = getattr(posterior, "network_input", None)
        mask = getattr(network_input, "person_mask", None)
        known = getattr(network_input, "person_mask_known", None)
        fit = getattr(posterior, "evidence_fit", None)
        terms = tuple(getattr(fit, "terms", ()) or ())
        reads_mask = proxy is not None and proxy.shape[0] - NUM_KEYPOINTS == 2
        text = shape_basis_text(mask is not None, reads_mask, terms)
        self.person_mask.visible = mask is not None and known is not None
        if mask is not None and known is not None:
            mask, known = np.asarray(mask, np.float32), np.asarray(known, bool)
            edges = (
                None if proxy is None else np.clip(proxy[0].detach().float().cpu().numpy(), 0, 1)
            )
            if edges is not None and edges.shape != mask.shape:
                edges = None
            mode = None if overlay_rgba is None else mode_in_crop(overlay_rgba, mask.shape[0])
            self.person_mask.image = person_mask_image(mask, known, edges, mode)
            if mode is not None:
                text += (
                    f" The most likely body's outline (red, in the *Person mask* image) covers "
                    f"the mask at IoU {mask_iou(mode, mask, known):.2f}."
                )
        self.shape_text.content = text


def build_teaching_section(gui: viser.GuiApi, actions: StateActions) -> TeachingSection:
    """The "Teaching" folder, wired to ``actions``."""
    with gui.add_folder("Teaching"):
        joint = gui.add_dropdown(
            "Joint", JOINT_LABELS, initial_value=joint_label(actions.state.selected_joint)
        )
        axes_text = gui.add_markdown("")
        proxy_edges = gui.add_image(np.zeros((64, 64, 3), np.uint8), label="Edges")
        proxy_heat = gui.add_image(np.zeros((64, 64, 3), np.uint8), label="Heatmaps")
        shape_text = gui.add_markdown("")
        person_mask = gui.add_image(np.zeros((64, 64, 3), np.uint8), label="Person mask")
        person_mask.visible = False
        with gui.add_folder("What am I looking at?", expand_by_default=False):
            gui.add_markdown(EXPLANATION)
    joint.on_update(
        lambda _: actions.sampling_changed(actions.state.select_joint(joint_name(joint.value)))
    )
    return TeachingSection(joint, axes_text, proxy_edges, proxy_heat, shape_text, person_mask)
