"""The training loop behind ``hkpd-train``.

One step: take the next synthetic batch (made ahead in a background thread), predict the
distributions, compute the scheduled losses (:mod:`hkpd.training.losses`), and take an Adam
step. Every ``log_every`` steps a row goes to ``train.csv``; every ``val_every`` steps the
network is evaluated on a fixed synthetic validation set (``val.csv``) and the curves PNG is
redrawn; checkpoints go to ``last.pt`` (atomically), which ``--resume`` continues from exactly:
the data stream is indexed by step, so a resumed run sees the batches it would have seen.

Under ``torchrun`` every process runs this loop on its own data stream with the network in
DistributedDataParallel (:mod:`hkpd.training.distributed`); rank 0 alone writes the run folder.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import torch
from tqdm import tqdm

from hkpd.body import BodyModel
from hkpd.devices import resolve_device
from hkpd.evaluation.synthetic import evaluate_batches
from hkpd.network import DistributionNetwork
from hkpd.network.checkpoint import (
    load_initial_weights,
    load_weights,
    random_states,
    read_checkpoint,
    restore_random_states,
    save_checkpoint,
)
from hkpd.network.config import NetworkConfig
from hkpd.poses import PoseSource, pose_source
from hkpd.synthesis.generator import (
    SyntheticBatches,
    SyntheticDataConfig,
    SyntheticDataGenerator,
    fixed_test_set,
)
from hkpd.synthesis.parallel import GeneratorSpec, ParallelBatches
from hkpd.training.config import TrainConfig, learning_rate_at
from hkpd.training.csv_logs import append_row, check_log, complete_row, truncate_log
from hkpd.training.curves import plot_training_curves
from hkpd.training.distributed import (
    Launch,
    average_and_any,
    detect_launch,
    end_process_group,
    gather_to_main,
    launch_device,
    rank_seed,
    start_process_group,
    wrap_for_training,
)
from hkpd.training.losses import compute_losses
from hkpd.training.prefetch import Prefetcher
from hkpd.training.schedule import LossSchedule, LossStage, LossWeights
from hkpd.training.stop_signals import StopSignals

CHECKPOINT_NAME = "last.pt"
LOGS = ("train.csv", "val.csv")
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

    ``weights`` (default: :class:`LossWeights` with the config's ``samples_loss_weight`` and
    ``mode_loss_weight``) are the weights of every term once it is on.
    """
    full = weights or LossWeights(
        joints2d_samples=config.samples_loss_weight,
        joints2d_mode=config.mode_loss_weight,
        shape_tpose_vertices=config.tpose_loss_weight,
    )
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


def _tensorboard_writer(out: Path):
    """A TensorBoard writer logging into ``out/tensorboard``."""
    try:
        from torch.utils.tensorboard import SummaryWriter
    except ImportError as error:
        raise ValueError(
            "--tensorboard needs the tensorboard package: pip install tensorboard"
        ) from error
    return SummaryWriter(str(out / "tensorboard"))


def _check_resumable(
    payload: dict, network_config: NetworkConfig, config: TrainConfig, path: Path, launch: Launch
) -> None:
    """Refuse a resume that cannot continue: another architecture, a finished run, or another
    number of processes (whose data streams and random states the checkpoint does not hold).

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
    saved_world = int(payload["train_config"].get("world_size", 1))
    if saved_world != launch.world_size:
        raise ValueError(
            f"--resume: the run in {path.parent} trained with {saved_world} process(es), this "
            f"launch has {launch.world_size}; resume it with torchrun --nproc-per-node "
            f"{saved_world} (or without torchrun for 1), or start a new run from its weights "
            f"with --init-weights {path}"
        )


@dataclass
class TrainingSetup:
    """Everything a run needs, built (and resumed) by :func:`build_training`."""

    config: TrainConfig
    device: torch.device
    out: Path
    body: BodyModel
    network_config: NetworkConfig
    network: DistributionNetwork
    optimizer: torch.optim.Optimizer
    schedule: LossSchedule
    data_config: SyntheticDataConfig
    val_poses: PoseSource
    launch: Launch = field(default_factory=Launch)
    model: torch.nn.Module | None = None
    step: int = 0
    samples_seen: int = 0

    @property
    def trained_module(self) -> torch.nn.Module:
        """What a training step calls: the network, or its DistributedDataParallel wrapper."""
        return self.network if self.model is None else self.model

    @property
    def checkpoint_path(self) -> Path:
        return self.out / CHECKPOINT_NAME


def build_training(
    config: TrainConfig, resume: bool = False, launch: Launch | None = None
) -> TrainingSetup:
    """Check the config and the paths, build data, network and optimiser, and resume.

    A refused resume (another architecture, a finished run, a foreign log) writes nothing.
    Under torchrun (``launch``, default: :func:`~hkpd.training.distributed.detect_launch`)
    this joins the process group after the checks, and only rank 0 writes the run folder.

    Raises:
        FileNotFoundError: a data path (pose bank, backgrounds, resume checkpoint) is missing.
        ValueError: a flag out of range, or a resume that cannot continue.
    """
    launch = detect_launch() if launch is None else launch
    config = replace(config.validate(), world_size=launch.world_size)
    _check_paths(config)
    device = launch_device(resolve_device(config.device), launch)
    out = Path(config.out)
    checkpoint_path = out / CHECKPOINT_NAME
    if resume and not checkpoint_path.is_file():
        raise FileNotFoundError(f"--resume: no checkpoint at {checkpoint_path}")
    val_poses = pose_source(config.poses, "val", config.pose_mix())
    pose_source(config.poses, "train", config.pose_mix())  # fails early on a bad bank
    network_config = config.network_config()
    payload = None
    if resume:
        payload = read_checkpoint(checkpoint_path, map_location=device)
        _check_resumable(payload, network_config, config, checkpoint_path, launch)
        for log in LOGS:
            check_log(out / log)
    if launch.is_main:
        out.mkdir(parents=True, exist_ok=True)
        config.save(out / "config.json")
    start_process_group(launch, device)
    torch.manual_seed(config.seed)
    network = DistributionNetwork(network_config).to(device)
    if config.shape_from_nll_only and hasattr(network.head, "detach_shape_input"):
        network.head.detach_shape_input = True  # the pose streams' shape inputs too
    if config.init_weights is not None and not resume:
        load_initial_weights(network, config.init_weights, device)
    if launch.rank > 0:  # the same initial weights everywhere, then each rank's own draws
        torch.manual_seed(rank_seed(config.seed, launch.rank))
    setup = TrainingSetup(
        config, device, out, BodyModel().to(device), network_config, network,
        torch.optim.Adam(network.parameters(), lr=config.learning_rate), build_schedule(config),
        config.data_config(), val_poses, launch, wrap_for_training(network, launch, device),
    )  # fmt: skip
    if payload is not None:
        _resume(setup, payload)
    return setup


def _resume(setup: TrainingSetup, payload: dict) -> None:
    """Weights, optimiser, counters and random states from a checkpoint; logs cut after it."""
    load_weights(setup.network, payload["model"], setup.out / CHECKPOINT_NAME)
    setup.optimizer.load_state_dict(payload["optimizer"])
    setup.step, setup.samples_seen = int(payload["step"]), int(payload["samples_seen"])
    if setup.launch.is_main:
        for log in LOGS:
            truncate_log(setup.out / log, setup.step)
    if setup.launch.distributed:
        restore_random_states(payload["rng_per_rank"][setup.launch.rank])
    elif "rng" in payload:  # checkpoints before format 2 did not keep them
        restore_random_states(payload["rng"])


def _batch_stream(setup: TrainingSetup):
    """Training batches from ``setup.step`` on: worker processes, or a background thread."""
    config = setup.config
    seed = rank_seed(config.seed, setup.launch.rank)
    if config.data_workers > 0 and setup.device.type == "cpu":
        spec = GeneratorSpec(
            config.poses, "train", setup.data_config, config.backgrounds, config.pose_mix()
        )
        return ParallelBatches(
            spec, config.batch_size, seed, start=setup.step, workers=config.data_workers
        )
    poses = pose_source(config.poses, "train", config.pose_mix())
    generator = SyntheticDataGenerator(
        poses, setup.data_config, setup.device, config.backgrounds, body=setup.body
    )
    return Prefetcher(SyntheticBatches(generator, config.batch_size, seed, setup.step))


class TrainingRun:
    """One run's loop: :meth:`step`, :meth:`log`, :meth:`validate`, :meth:`save`, :meth:`run`.

    Under torchrun every rank runs it; :meth:`step` and :meth:`save` are the points where the
    ranks meet, :meth:`log` and :meth:`validate` happen on rank 0 alone.

    Args:
        setup: from :func:`build_training`.
        show_progress: draw a progress bar (rank 0 only).
    """

    def __init__(self, setup: TrainingSetup, show_progress: bool = True) -> None:
        self.setup = setup
        self.config = setup.config
        self.is_main = setup.launch.is_main
        use_board = self.config.tensorboard and self.is_main
        self.board = _tensorboard_writer(setup.out) if use_board else None
        self.use_amp = self.config.amp and setup.device.type == "cuda"
        self.validation_set: list | None = None
        self.last_validation: dict[str, float] = {}
        self.started = time.perf_counter()
        self.deadline = None
        if self.config.max_minutes is not None:
            self.deadline = self.started + 60.0 * self.config.max_minutes
        self.signals = StopSignals(force_on_second_interrupt=not setup.launch.distributed)
        self.stop_requested = self.out_of_time = False
        self.window_start, self.window_samples = self.started, 0
        self.progress = tqdm(
            total=self.config.steps, initial=setup.step,
            disable=not (show_progress and self.is_main), unit="step", dynamic_ncols=True,
        )  # fmt: skip

    def step(self, batch) -> tuple[dict[str, torch.Tensor], float]:
        """One optimiser step on ``batch``; returns the loss terms (averaged over the ranks)
        and the learning rate, and notes whether any rank asks to stop."""
        setup = self.setup
        weights = setup.schedule.weights_at(setup.step)
        with torch.autocast(setup.device.type, dtype=torch.bfloat16, enabled=self.use_amp):
            output = setup.trained_module(batch.proxy)
        terms = compute_losses(
            output, batch, setup.body, weights, self.config.num_samples,
            shape_from_nll_only=self.config.shape_from_nll_only,
        )  # fmt: skip
        setup.optimizer.zero_grad(set_to_none=True)
        terms["total"].backward()  # DistributedDataParallel averages the gradients here
        torch.nn.utils.clip_grad_norm_(setup.network.parameters(), 10.0)
        rate = learning_rate_at(setup.step, self.config)
        for group in setup.optimizer.param_groups:
            group["lr"] = rate
        setup.optimizer.step()
        setup.step += 1
        global_batch = batch.batch_size * setup.launch.world_size
        setup.samples_seen += global_batch
        self.window_samples += global_batch
        past_deadline = self.deadline is not None and time.perf_counter() >= self.deadline
        terms, (self.stop_requested, self.out_of_time) = average_and_any(
            terms, (self.signals.requested, past_deadline), setup.launch
        )
        total = float(terms["total"].detach())
        if not math.isfinite(total):
            self.save()
            raise FloatingPointError(
                f"the loss became {total} at step {setup.step}; the last checkpoint is kept at "
                f"{setup.checkpoint_path}. Try a lower --learning-rate."
            )
        stage = setup.schedule.stage_at(setup.step - 1).name
        self.progress.set_postfix(loss=f"{total:.3f}", stage=stage)
        self.progress.update(1)
        return terms, rate

    def log(self, terms: dict[str, torch.Tensor], rate: float) -> None:
        """One row of ``train.csv`` (and TensorBoard); ``samples_per_second`` counts every
        rank's examples."""
        now = time.perf_counter()
        samples_rate = self.window_samples / max(now - self.window_start, 1e-9)
        self.window_start, self.window_samples = now, 0
        row = {
            "step": self.setup.step,
            "seconds": round(now - self.started, 2),
            "samples_per_second": round(samples_rate, 2),
            "learning_rate": rate,
        }
        row |= {name: float(value.detach()) for name, value in terms.items()}
        append_row(self.setup.out / "train.csv", complete_row(row))
        if self.board is not None:
            for name, value in row.items():
                if name != "step":
                    self.board.add_scalar(f"train/{name}", value, self.setup.step)

    def validate(self) -> dict[str, float]:
        """Metrics on the fixed validation set, appended to ``val.csv``; curves redrawn."""
        setup = self.setup
        if self.validation_set is None:
            val_generator = SyntheticDataGenerator(
                setup.val_poses, setup.data_config, setup.device, self.config.backgrounds,
                body=setup.body,
            )  # fmt: skip
            self.validation_set = fixed_test_set(
                val_generator, self.config.val_size, VALIDATION_SEED,
                min(self.config.batch_size, 50),
            )  # fmt: skip
        setup.network.eval()
        metrics = evaluate_batches(setup.network, self.validation_set, setup.body)
        setup.network.train()
        append_row(setup.out / "val.csv", {"step": setup.step, **metrics})
        if self.board is not None:
            for name, value in metrics.items():
                self.board.add_scalar(f"val/{name}", value, setup.step)
        self.draw_curves()
        return metrics

    def save(self) -> Path:
        """The checkpoint (weights, optimiser, counters, random states), atomically.

        Under torchrun every rank calls it at the same step: rank 0 gathers the others'
        random states and writes the file.
        """
        setup = self.setup
        states = gather_to_main(random_states(), setup.launch)
        if not self.is_main:
            return setup.checkpoint_path
        return save_checkpoint(
            setup.checkpoint_path, setup.network, setup.network_config.to_dict(), setup.step,
            self.config.to_dict(), setup.samples_seen, setup.optimizer,
            rank_random_states=states if setup.launch.distributed else None,
        )  # fmt: skip

    def draw_curves(self) -> None:
        out = self.setup.out
        plot_training_curves(out / "train.csv", out / "val.csv", out / "curves.png")

    def say(self, line: str) -> None:
        """A line of the run's story, from rank 0 only."""
        if self.is_main:
            self.progress.write(line)

    def run(self) -> TrainingResult:
        """Train to ``steps`` (or ``max_minutes``, or Ctrl-C / SIGTERM), then save and validate.

        The stop handlers stay in place until the run is saved: under torchrun every worker
        gets the terminal's Ctrl-C and then torchrun's copy of it.
        """
        config, setup = self.config, self.setup
        launch = setup.launch
        if launch.distributed:
            self.say(
                f"{launch.world_size} processes x batch {config.batch_size} = global batch "
                f"{launch.world_size * config.batch_size} a step, learning rate "
                f"{config.learning_rate:g} (samples counted over all processes)"
            )
        with self.signals:
            self._train_steps()
            interrupted = self.stop_requested
            if interrupted:
                self.say(f"interrupted at step {setup.step}; saving {setup.checkpoint_path}")
            self.save()
            if not interrupted and self.is_main:
                self.last_validation = self.validate()
                print(f"final (step {setup.step}): " + _format_metrics(self.last_validation))
            if self.is_main:
                self.draw_curves()
        if self.board is not None:
            self.board.close()
        return TrainingResult(
            setup.checkpoint_path, setup.step, setup.samples_seen,
            time.perf_counter() - self.started, self.last_validation, interrupted,
            self.out_of_time and not interrupted and setup.step < config.steps,
        )  # fmt: skip

    def _train_steps(self) -> None:
        """Steps until ``steps``, the clock, or a stop request, all ranks at the same step."""
        config, setup = self.config, self.setup
        stream = _batch_stream(setup)
        setup.trained_module.train()
        try:
            while setup.step < config.steps:
                terms, rate = self.step(next(stream))
                self._after_step(terms, rate)
                if self.stop_requested or self.out_of_time:
                    break
        except KeyboardInterrupt:  # a second Ctrl-C alone, or one before the handlers
            if setup.launch.distributed:
                raise  # mid-step: the other ranks cannot meet this one in a checkpoint
            self.stop_requested = True
        finally:
            self.progress.close()
            stream.close()

    def _after_step(self, terms: dict, rate: float) -> None:
        """Log, validate and checkpoint on their schedules (logs and validation on rank 0)."""
        config, step = self.config, self.setup.step
        if self.is_main and (step % config.log_every == 0 or step == config.steps):
            self.log(terms, rate)
        validating = config.val_every and step % config.val_every == 0 and step < config.steps
        if self.is_main and validating:
            self.last_validation = self.validate()
            self.say(f"step {step}: " + _format_metrics(self.last_validation))
        if step % config.checkpoint_every == 0:
            self.save()
        if self.out_of_time and not self.stop_requested and step < config.steps:
            self.say(
                f"--max-minutes {config.max_minutes:g} reached at step {step}; saving "
                f"{self.setup.checkpoint_path} (continue with --resume)"
            )


def train(
    config: TrainConfig,
    resume: bool = False,
    show_progress: bool = True,
    launch: Launch | None = None,
) -> TrainingResult:
    """Run (or resume) a training run as configured; see the module docstring.

    Under torchrun (``launch``, default: detected from the environment) every process calls
    it; they leave the process group when the run ends.

    Raises:
        FileNotFoundError: a data path (pose bank, backgrounds, resume checkpoint) is missing.
        ValueError: a flag out of range, or a resume that cannot continue.
    """
    setup = build_training(config, resume, launch)
    result = None
    try:
        result = TrainingRun(setup, show_progress).run()
    finally:
        end_process_group(wait_for_all=result is not None)
    return result


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
