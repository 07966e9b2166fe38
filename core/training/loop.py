"""The training loop behind ``hkpd-train``.

One step: take the next synthetic batch (made ahead in a background thread), predict the
distributions, compute the scheduled losses (:mod:`hkpd.training.losses`), and take an Adam
step. Every ``log_every`` steps a row goes to ``train.csv``; every ``val_every`` steps the
network is evaluated on a fixed synthetic validation set (``val.csv``) and the curves PNG is
redrawn; checkpoints go to ``last.pt`` (atomically), which ``--resume`` continues from exactly:
the data stream is indexed by step, so a resumed run sees the batches it would have seen.
"""

from __future__ import annotations

import csv
import math
import signal
import threading
import time
from dataclasses import dataclass, replace
from pathlib import Path

import torch
from tqdm import tqdm

from hkpd.body import BodyModel
from hkpd.devices import resolve_device
from hkpd.network import DistributionNetwork
from hkpd.network.config import NetworkConfig
from hkpd.poses import pose_source
from hkpd.synthesis.generator import (
    SyntheticBatches,
    SyntheticDataGenerator,
    fixed_test_set,
)
from hkpd.synthesis.parallel import GeneratorSpec, ParallelBatches
from hkpd.training.checkpoint import (
    load_initial_weights,
    read_checkpoint,
    restore_random_states,
    save_checkpoint,
)
from hkpd.training.config import TrainConfig, learning_rate_at
from hkpd.training.curves import plot_training_curves
from hkpd.training.losses import compute_losses
from hkpd.training.prefetch import Prefetcher
from hkpd.training.schedule import LOSS_TERMS, LossSchedule, LossStage, LossWeights

CHECKPOINT_NAME = "last.pt"
VALIDATION_SEED = 7


@dataclass
class TrainingResult:
    """What a finished (or interrupted) run leaves behind."""

    checkpoint: Path
    steps: int
    samples_seen: int
    seconds: float
    last_validation: dict[str, float]
    interrupted: bool = False
    out_of_time: bool = False


def build_schedule(config: TrainConfig, weights: LossWeights | None = None) -> LossSchedule:
    """The paper's staged losses with the config's boundaries (-1 switches a stage off).

    ``weights`` (default: :class:`LossWeights` with the config's ``samples_loss_weight``) are the
    weights of every term once it is on.
    """
    full = weights or LossWeights(joints2d_samples=config.samples_loss_weight)
    events = []
    if config.samples_loss_from >= 0:
        events.append((config.samples_loss_from, "joints2d_samples"))
    if config.joints3d_loss_from >= 0:
        events.append((config.joints3d_loss_from, "joints3d_mode"))
    current = replace(full, joints2d_samples=0.0, joints3d_mode=0.0)
    stages = [LossStage(0, current, "nll+global+2d-mode")]
    for start, term in sorted(events):
        current = replace(current, **{term: getattr(full, term)})
        label = "+2d-samples" if term == "joints2d_samples" else "+3d-joints"
        if start == 0:
            stages[0] = LossStage(0, current, stages[0].name + label)
        elif start == stages[-1].start_step:
            stages[-1] = LossStage(start, current, stages[-1].name + label)
        else:
            stages.append(LossStage(start, current, label))
    return LossSchedule(tuple(stages))


def _check_paths(config: TrainConfig) -> None:
    if config.backgrounds is not None and not Path(config.backgrounds).is_dir():
        raise FileNotFoundError(f"background folder {config.backgrounds} does not exist")


def _stop_on_sigterm() -> None:
    """Treat SIGTERM (and SIGINT, even where a background launch ignored it) like Ctrl-C: the
    loop then saves a checkpoint and stops cleanly."""
    if threading.current_thread() is not threading.main_thread():
        return

    def interrupt(signum, frame) -> None:
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, interrupt)
    signal.signal(signal.SIGINT, interrupt)


def _tensorboard_writer(out: Path):
    """A TensorBoard writer logging into ``out/tensorboard``."""
    try:
        from torch.utils.tensorboard import SummaryWriter
    except ImportError as error:
        raise ValueError(
            "--tensorboard needs the tensorboard package: pip install tensorboard"
        ) from error
    return SummaryWriter(str(out / "tensorboard"))


def _append_csv(path: Path, row: dict[str, float]) -> None:
    """Append ``row``; a row with columns the file lacks (a run resumed by a newer version that
    logs more metrics) rewrites the file with the extra columns, left empty in older rows."""
    columns = list(row)
    if path.exists():
        with path.open(newline="") as handle:
            header = next(csv.reader(handle), [])
        if header and not set(columns) <= set(header):
            with path.open(newline="") as handle:
                rows = list(csv.DictReader(handle))
            header += [column for column in columns if column not in header]
            with path.open("w", newline="") as handle:
                writer = csv.DictWriter(handle, fieldnames=header)
                writer.writeheader()
                writer.writerows(rows)
        columns = header or columns
    new = not path.exists() or path.stat().st_size == 0
    with path.open("a", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=columns)
        if new:
            writer.writeheader()
        writer.writerow(row)


def _check_resumable(
    payload: dict, network_config: NetworkConfig, config: TrainConfig, path: Path
) -> None:
    """Refuse a resume that cannot continue: another architecture, or a finished run.

    Raises:
        ValueError: with what to do instead.
    """
    saved = NetworkConfig.from_dict(payload["network_config"]).to_dict()
    wanted = network_config.to_dict()
    if saved != wanted:
        changed = sorted(key for key in saved if saved[key] != wanted.get(key))
        had = ", ".join(f"{key}={saved[key]}" for key in changed)
        asked = ", ".join(f"{key}={wanted.get(key)}" for key in changed)
        raise ValueError(
            f"--resume: {path} holds a network with {had}, but this run asks for {asked}; drop "
            "those flags to continue it, or train into a new --out"
        )
    if "optimizer" not in payload:
        raise ValueError(f"--resume: {path} holds exported weights without an optimiser state")
    if int(payload["step"]) >= config.steps:
        raise ValueError(
            f"--resume: the run in {path.parent} already finished ({int(payload['step'])} of "
            f"--steps {config.steps}); give a larger --steps to train it further"
        )


def _check_csv(path: Path) -> None:
    """Raise a ValueError when a log to resume has rows but no ``step`` column."""
    if not path.exists():
        return
    with path.open(newline="") as handle:
        header = next(csv.reader(handle), [])
        has_rows = next(csv.reader(handle), None) is not None
    if has_rows and "step" not in header:
        raise ValueError(
            f"--resume: {path} has no 'step' column, so it was not written by hkpd-train; "
            "move it away to continue"
        )


def _truncate_csv(path: Path, last_step: int) -> None:
    """Drop rows after ``last_step`` (a resumed run rewrites them)."""
    if not path.exists():
        return
    with path.open() as handle:
        rows = list(csv.DictReader(handle))
    if not rows:
        return
    kept = [row for row in rows if float(row["step"]) <= last_step]
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(kept)


def train(config: TrainConfig, resume: bool = False, show_progress: bool = True) -> TrainingResult:
    """Run (or resume) a training run as configured; see the module docstring.

    Raises:
        FileNotFoundError: a data path (pose bank, backgrounds, resume checkpoint) is missing.
        ValueError: a learning rate is not positive.
    """
    from hkpd.evaluation.synthetic import evaluate_batches

    config.validate()
    _check_paths(config)
    device = resolve_device(config.device)
    out = Path(config.out)
    checkpoint_path = out / CHECKPOINT_NAME
    if resume and not checkpoint_path.is_file():
        raise FileNotFoundError(f"--resume: no checkpoint at {checkpoint_path}")
    train_poses = pose_source(config.poses, "train", config.pose_mix())
    val_poses = pose_source(config.poses, "val", config.pose_mix())
    network_config = NetworkConfig(
        backbone_base_width=config.backbone_base_width,
        pose_head=config.pose_head,
        image_size=config.image_size,
        concentration_gain=config.concentration_gain,
    )
    payload = None
    if resume:  # checked before anything in the run folder is written
        payload = read_checkpoint(checkpoint_path, map_location=device)
        _check_resumable(payload, network_config, config, checkpoint_path)
        for log in ("train.csv", "val.csv"):
            _check_csv(out / log)
    out.mkdir(parents=True, exist_ok=True)
    config.save(out / "config.json")

    torch.manual_seed(config.seed)
    body = BodyModel().to(device)
    data_config = config.data_config()
    generator = SyntheticDataGenerator(
        train_poses, data_config, device=device, background_dir=config.backgrounds, body=body
    )
    network = DistributionNetwork(network_config).to(device)
    if config.init_weights is not None and not resume:
        load_initial_weights(network, config.init_weights, device)
    optimizer = torch.optim.Adam(network.parameters(), lr=config.learning_rate)
    step, samples_seen = 0, 0
    if payload is not None:
        network.load_state_dict(payload["model"])
        optimizer.load_state_dict(payload["optimizer"])
        step, samples_seen = int(payload["step"]), int(payload["samples_seen"])
        for log in ("train.csv", "val.csv"):
            _truncate_csv(out / log, step)
        if "rng" in payload:  # checkpoints before format 2 did not keep them
            restore_random_states(payload["rng"])
    schedule = build_schedule(config)
    board = _tensorboard_writer(out) if config.tensorboard else None
    use_amp = config.amp and device.type == "cuda"

    def save() -> Path:
        return save_checkpoint(
            checkpoint_path,
            network,
            network_config.to_dict(),
            step,
            config.to_dict(),
            samples_seen,
            optimizer,
        )

    validation_set = None
    last_validation: dict[str, float] = {}

    def validate() -> dict[str, float]:
        nonlocal validation_set
        if validation_set is None:
            val_generator = SyntheticDataGenerator(
                val_poses, data_config, device=device, background_dir=config.backgrounds, body=body
            )
            validation_set = fixed_test_set(
                val_generator, config.val_size, VALIDATION_SEED, min(config.batch_size, 50)
            )
        network.eval()
        metrics = evaluate_batches(network, validation_set, body)
        network.train()
        _append_csv(out / "val.csv", {"step": step, **metrics})
        if board is not None:
            for name, value in metrics.items():
                board.add_scalar(f"val/{name}", value, step)
        plot_training_curves(out / "train.csv", out / "val.csv", out / "curves.png")
        return metrics

    if config.data_workers > 0 and device.type == "cpu":
        spec = GeneratorSpec(
            config.poses, "train", data_config, config.backgrounds, config.pose_mix()
        )
        stream = ParallelBatches(
            spec, config.batch_size, config.seed, start=step, workers=config.data_workers
        )
    else:
        stream = Prefetcher(SyntheticBatches(generator, config.batch_size, config.seed, start=step))
    _stop_on_sigterm()
    started = time.perf_counter()
    window_start, window_samples = started, 0
    interrupted = out_of_time = False
    deadline = None if config.max_minutes is None else started + 60.0 * config.max_minutes
    progress = tqdm(
        total=config.steps, initial=step, disable=not show_progress, unit="step", dynamic_ncols=True
    )
    network.train()
    try:
        while step < config.steps:
            batch = next(stream)
            weights = schedule.weights_at(step)
            with torch.autocast(device.type, dtype=torch.bfloat16, enabled=use_amp):
                output = network(batch.proxy)
            terms = compute_losses(output, batch, body, weights, config.num_samples)
            optimizer.zero_grad(set_to_none=True)
            terms["total"].backward()
            torch.nn.utils.clip_grad_norm_(network.parameters(), 10.0)
            rate = learning_rate_at(step, config)
            for group in optimizer.param_groups:
                group["lr"] = rate
            optimizer.step()
            step += 1
            samples_seen += batch.batch_size
            window_samples += batch.batch_size
            total = float(terms["total"].detach())
            if not math.isfinite(total):
                save()
                raise FloatingPointError(
                    f"the loss became {total} at step {step}; the last checkpoint is kept at "
                    f"{checkpoint_path}. Try a lower --learning-rate."
                )
            progress.set_postfix(loss=f"{total:.3f}", stage=schedule.stage_at(step - 1).name)
            progress.update(1)
            if step % config.log_every == 0 or step == config.steps:
                now = time.perf_counter()
                samples_rate = window_samples / max(now - window_start, 1e-9)
                window_start, window_samples = now, 0
                row = {
                    "step": step,
                    "seconds": round(now - started, 2),
                    "samples_per_second": round(samples_rate, 2),
                    "learning_rate": rate,
                }
                row |= {name: float(value.detach()) for name, value in terms.items()}
                _append_csv(out / "train.csv", _complete_row(row))
                if board is not None:
                    for name, value in row.items():
                        if name != "step":
                            board.add_scalar(f"train/{name}", value, step)
            if config.val_every and step % config.val_every == 0 and step < config.steps:
                last_validation = validate()
                progress.write(f"step {step}: " + _format_metrics(last_validation))
            if step % config.checkpoint_every == 0:
                save()
            if deadline is not None and step < config.steps and time.perf_counter() >= deadline:
                out_of_time = True
                progress.write(
                    f"--max-minutes {config.max_minutes:g} reached at step {step}; saving "
                    f"{checkpoint_path} (continue with --resume)"
                )
                break
    except KeyboardInterrupt:
        interrupted = True
        progress.write(f"interrupted at step {step}; saving {checkpoint_path}")
    finally:
        progress.close()
        stream.close()
    save()
    if not interrupted:
        last_validation = validate()
        print(f"final (step {step}): " + _format_metrics(last_validation))
    plot_training_curves(out / "train.csv", out / "val.csv", out / "curves.png")
    if board is not None:
        board.close()
    return TrainingResult(
        checkpoint_path, step, samples_seen, time.perf_counter() - started, last_validation,
        interrupted, out_of_time,
    )  # fmt: skip


_LOG_TERMS = (*LOSS_TERMS, "total")


def _complete_row(row: dict[str, float]) -> dict[str, float]:
    """Every loss column in a fixed order (inactive terms empty), so CSV columns never shift."""
    fixed = {key: row[key] for key in ("step", "seconds", "samples_per_second", "learning_rate")}
    return fixed | {name: row.get(name, "") for name in _LOG_TERMS}


HEADLINE_METRICS = (
    "mpjpe_sc",
    "mpjpe_pa",
    "pve_t_sc",
    "joint_error_2d_mode",
    "joint_error_2d_samples",
)


def _format_metrics(metrics: dict[str, float]) -> str:
    """The headline metrics in one line (all of them are in val.csv)."""
    units = {"joint_error_2d_mode": "px", "joint_error_2d_samples": "px"}
    return ", ".join(
        f"{key} {metrics[key]:.1f} {units.get(key, 'mm')}" for key in HEADLINE_METRICS
        if key in metrics
    )  # fmt: skip
