"""Reading SMPL model files (.npz and chumpy/scipy .pkl) without SMPL, chumpy or real data."""

from __future__ import annotations

import os
import pickle
import sys
import types

import numpy as np
import pytest
import scipy.sparse
import torch
from synthetic_body import synthetic_body

from hkpd.body import BodyModel, load_body_asset
from hkpd.kinematic_tree import SMPL_JOINT_NAMES, SMPL_PARENTS

SMPL_ROOT_PARENT = np.uint32(4294967295)


def smpl_fields(root_parent: int = -1, shape_count: int = 12) -> dict[str, np.ndarray]:
    """A synthetic body in SMPL's own field names and conventions (float64, uint32 faces)."""
    body = synthetic_body(num_betas=shape_count, with_posedirs=True, with_keypoints=False)
    kintree = np.array([SMPL_PARENTS, range(24)], dtype=np.int64)
    kintree[0, 0] = root_parent
    return {
        "v_template": body["v_template"],
        "shapedirs": body["shapedirs"],
        "posedirs": body["posedirs"],
        "J_regressor": body["J_regressor"],
        "weights": body["skinning_weights"],
        "kintree_table": kintree.astype(np.uint32) if root_parent > 0 else kintree,
        "f": body["faces"].astype(np.uint32),
        "J": body["J_regressor"] @ body["v_template"],
        "bs_style": np.array("lbs"),
    }


def assert_converted(asset, fields: dict[str, np.ndarray]) -> None:
    regressor = np.asarray(fields["J_regressor"])
    shapedirs = fields["shapedirs"][..., :10]
    assert asset.num_betas == 10 and asset.shapedirs.dtype == np.float32
    assert np.allclose(asset.v_template, fields["v_template"], atol=1e-6)
    assert np.allclose(asset.shapedirs, shapedirs, atol=1e-6)
    assert np.allclose(asset.joint_template, regressor @ fields["v_template"], atol=1e-6)
    expected = np.einsum("jv,vck->jck", regressor, shapedirs)
    assert np.allclose(asset.joint_shapedirs, expected, atol=1e-6)
    assert np.allclose(asset.posedirs, fields["posedirs"], atol=1e-6)
    assert np.allclose(asset.skinning_weights, fields["weights"], atol=1e-6)
    assert tuple(asset.parents) == SMPL_PARENTS
    assert np.array_equal(asset.faces, fields["f"].astype(np.int32))
    assert np.array_equal(asset.part_labels, fields["weights"].argmax(axis=1))
    assert asset.joint_names == SMPL_JOINT_NAMES and asset.part_names == SMPL_JOINT_NAMES
    assert asset.keypoint_regressor is None


def assert_model_poses(path) -> None:
    body = BodyModel.from_file(path)
    assert body.num_betas == 10 and body.posedirs is not None
    betas = torch.randn(2, 10)
    body_pose = torch.eye(3).expand(2, 23, 3, 3)
    output = body(betas, body_pose)
    assert output.keypoints is None and output.vertices.shape == (2, body.num_vertices, 3)
    assert torch.allclose(output.vertices, body.tpose(betas), atol=1e-6)


def test_smpl_npz_is_converted(tmp_path) -> None:
    fields = smpl_fields(root_parent=-1)
    path = tmp_path / "SMPL_NEUTRAL.npz"
    np.savez(path, **fields)
    asset = load_body_asset(path)
    assert_converted(asset, fields)
    assert "SMPL" in asset.info["source"] and asset.source.startswith(str(path))
    assert load_body_asset(path, num_betas=12).num_betas == 12
    assert_model_poses(path)


class ChumpyState(dict):
    """What a pickled chumpy.ch.Ch carries: its __dict__, with the array under 'x'."""


def chumpy_state(**fields) -> ChumpyState:
    return ChumpyState(_dirty_vars=set(), _itr=None, _depends_on_deps={}, **fields)


def pickle_with_fake_chumpy(path, content, monkeypatch, protocol: int = 2) -> None:
    """Write ``content`` as a Python-2-readable pickle, ChumpyStates as ``chumpy.ch.Ch`` objects.

    The fake ``chumpy`` modules exist only while pickling, so loading cannot use them.
    """
    fake_ch = type("Ch", (), {"__module__": "chumpy.ch"})
    package, module = types.ModuleType("chumpy"), types.ModuleType("chumpy.ch")
    module.Ch = fake_ch
    package.ch = module

    def as_chumpy(value):
        if not isinstance(value, ChumpyState):
            return value
        instance = fake_ch()
        instance.__dict__.update(value)
        return instance

    with monkeypatch.context() as patch:
        patch.setitem(sys.modules, "chumpy", package)
        patch.setitem(sys.modules, "chumpy.ch", module)
        with open(path, "wb") as file:
            pickle.dump({key: as_chumpy(value) for key, value in content.items()}, file, protocol)
    assert "chumpy" not in sys.modules and "chumpy.ch" not in sys.modules


@pytest.mark.parametrize("protocol", [0, 2])
def test_smpl_pkl_with_chumpy_and_sparse_regressor_is_converted(
    tmp_path, monkeypatch, protocol
) -> None:
    fields = smpl_fields(root_parent=SMPL_ROOT_PARENT)
    content = dict(fields)
    content["shapedirs"] = chumpy_state(x=fields["shapedirs"])
    content["J_regressor"] = scipy.sparse.csc_matrix(fields["J_regressor"])
    content["J_regressor_prior"] = scipy.sparse.csc_matrix(fields["J_regressor"])
    path = tmp_path / "basicModel_neutral_lbs_10_207_0_v1.0.0.pkl"
    pickle_with_fake_chumpy(path, content, monkeypatch, protocol)
    assert b"chumpy.ch" in path.read_bytes()
    # Name numpy and scipy classes by the module paths that the original SMPL files use.
    legacy = path.read_bytes().replace(b"numpy._core.multiarray\n", b"numpy.core.multiarray\n")
    path.write_bytes(legacy.replace(b"scipy.sparse._csc\n", b"scipy.sparse.csc\n"))
    assert b"numpy.core.multiarray\n" in path.read_bytes()

    asset = load_body_asset(path)
    assert_converted(asset, fields)
    assert_model_poses(path)


def test_chumpy_object_without_x_falls_back_to_its_only_array(tmp_path, monkeypatch) -> None:
    fields = smpl_fields()
    wrapped = chumpy_state(a=fields["shapedirs"])
    path = tmp_path / "model.pkl"
    pickle_with_fake_chumpy(path, {**fields, "shapedirs": wrapped}, monkeypatch)
    assert np.allclose(load_body_asset(path).shapedirs, fields["shapedirs"][..., :10], atol=1e-6)

    empty = chumpy_state()
    pickle_with_fake_chumpy(path, {**fields, "shapedirs": empty}, monkeypatch)
    with pytest.raises(ValueError, match=r"cannot find the array inside pickled chumpy\.ch\.Ch"):
        load_body_asset(path)


class RunsACommand:
    def __init__(self, command: str) -> None:
        self.command = command

    def __reduce__(self):
        return (os.system, (self.command,))


@pytest.mark.parametrize("payload", ["os.system", "eval"])
def test_pickles_naming_other_classes_are_refused(tmp_path, payload) -> None:
    marker = tmp_path / "was_run"
    if payload == "os.system":
        hostile = RunsACommand(f"touch {marker}")
    else:

        class Evaluates:
            def __reduce__(self):
                return (eval, (f"open({str(marker)!r}, 'w')",))

        hostile = Evaluates()
    path = tmp_path / "model.pkl"
    path.write_bytes(pickle.dumps({**smpl_fields(), "v_template": hostile}, protocol=2))
    with pytest.raises(pickle.UnpicklingError, match="refusing to load"):
        load_body_asset(path)
    assert not marker.exists()


def test_missing_scipy_is_reported_with_the_fix(tmp_path, monkeypatch) -> None:
    fields = smpl_fields()
    path = tmp_path / "model.pkl"
    content = {**fields, "J_regressor": scipy.sparse.csc_matrix(fields["J_regressor"])}
    path.write_bytes(pickle.dumps(content, protocol=2))
    monkeypatch.setitem(sys.modules, "scipy.sparse", None)
    with pytest.raises(ImportError, match="pip install scipy"):
        load_body_asset(path)


def test_bad_smpl_files_name_the_field(tmp_path) -> None:
    fields = smpl_fields()
    path = tmp_path / "smpl.npz"
    np.savez(path, **{key: value for key, value in fields.items() if key != "weights"})
    with pytest.raises(ValueError, match=r"lacks field\(s\) \['weights'\]"):
        load_body_asset(path)
    np.savez(path, **{**fields, "shapedirs": fields["shapedirs"][..., :8]})
    with pytest.raises(ValueError, match="asked for 10 shape coefficients but field 'shapedirs'"):
        load_body_asset(path)
    np.savez(path, **{**fields, "J_regressor": fields["J_regressor"][:20]})
    with pytest.raises(ValueError, match=r"smpl\.npz \(SMPL\): field 'J_regressor' must have"):
        load_body_asset(path)
    (tmp_path / "list.pkl").write_bytes(pickle.dumps([1, 2], protocol=2))
    with pytest.raises(ValueError, match="holds list"):
        load_body_asset(tmp_path / "list.pkl")
    (tmp_path / "model.obj").write_text("v 0 0 0\n")
    with pytest.raises(ValueError, match="unknown body model format"):
        load_body_asset(tmp_path / "model.obj")
