"""What TL-AC logs: the statistics an update gathers over its minibatches
(:class:`UpdateLog`) and their summary (:func:`summarize_update`), what ``learn`` writes at each
logging step (:func:`log_metrics`) and shows on its progress bar (:func:`progress_text`), both
kept for one ``learn`` call by :class:`LearnProgress`."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from tlac.algorithms.common import make_progress_bar
from tlac.recording import EpisodeRecorder, MetricWindow, find_episode_recorder, next_log_step


@dataclass
class UpdateLog:
    """What one update gathers over its minibatches for the logs."""

    losses_and_kls: list[torch.Tensor] = field(default_factory=list)
    """Per minibatch: [policy loss per level, value loss, approximate KL per level]."""
    clip_fractions: list[torch.Tensor] = field(default_factory=list)
    imitation: list[torch.Tensor] = field(default_factory=list)
    stopped_early: bool = False


def summarize_update(log: UpdateLog, levels: int) -> dict[str, float]:
    """The means over an update's minibatches of the losses, KLs and clip fractions, under
    SB3's names where SB3 has one (the low level is the student's policy).

    >>> log = UpdateLog([torch.tensor([1.0, 2.0, 0.1]), torch.tensor([3.0, 4.0, 0.3])],
    ...                 [torch.tensor([0.5])])
    >>> summary = summarize_update(log, 1)
    >>> (summary["train/policy_loss_low"], summary["train/value_loss"],
    ...  summary["train/clip_fraction"])
    (2.0, 3.0, 0.5)
    """
    names = ["low", "high"][:levels]
    keys = [f"policy_loss_{lv}" for lv in names] + ["value_loss"]
    keys += [f"approx_kl_{lv}" for lv in names]
    means = torch.stack(log.losses_and_kls).mean(0).tolist()
    out = {f"train/{k}": v for k, v in zip(keys, means, strict=True)}
    fractions = torch.stack(log.clip_fractions).mean(0).tolist()
    out["train/clip_fraction"] = fractions[0]
    if len(fractions) > 1:
        out["train/clip_fraction_high"] = fractions[1]
    return out


def log_metrics(
    model: Any,
    metrics: dict[str, float],
    fps: float,
    episodes: EpisodeRecorder | None,
    sb3_output: bool,
    sb3_only: dict[str, float] | None = None,
) -> None:
    """A logging step of ``model.learn``: the window's statistics, the speed and the recent
    training episodes, to the run folder's progress.csv and (verbose / TensorBoard) SB3's
    logger; ``sb3_only``: scalars for SB3's logger alone (the high level's choices, which a
    run folder keeps per region in teacher_usage.csv)."""
    metrics["time/fps"] = fps
    metrics["time/total_timesteps"] = model.num_timesteps
    if episodes is not None and episodes.episode_returns:
        metrics["rollout/ep_rew_mean"] = episodes.mean_recent_return()
        metrics["rollout/ep_len_mean"] = episodes.mean_recent_length()
    if model.recorder is not None:
        model.recorder.record_metrics(model.num_timesteps, metrics)
    if sb3_output:
        for key, value in {**metrics, **(sb3_only or {})}.items():
            model.logger.record(key, value)
        model.logger.dump(model.num_timesteps)


def progress_text(
    episodes: EpisodeRecorder | None,
    usage: np.ndarray,
    teacher_names: list[str],
    span: str = "recent:",
) -> str:
    """The progress bar's text: the training return (teachers included; the student alone is
    what evaluations print) and the share of each teacher and the agent in the high level's
    choices ``usage`` (counts), made over ``span``: the recent ones while ``learn`` runs, all
    of the call's at its end.

    >>> progress_text(None, np.array([3.0, 1.0]), ["optimal"])
    'training return nan | recent: optimal 75% agent 25%'
    >>> progress_text(None, np.array([26.0, 74.0]), ["optimal"], "all 100 steps:")
    'training return nan | all 100 steps: optimal 26% agent 74%'
    """
    ret = episodes.mean_recent_return() if episodes is not None else float("nan")
    parts = [f"training return {ret:.3g}"]
    if teacher_names and usage.sum() > 0:
        frac = usage / usage.sum()
        names = [*teacher_names, "agent"]
        shares = " ".join(f"{n} {f:.0%}" for n, f in zip(names, frac, strict=True))
        parts.append(f"{span} {shares}")
    return " | ".join(parts)


class LearnProgress:
    """What one ``learn`` call of ``model`` logs and shows while it runs: the logging window
    (kept on the model, ``model._log_window``, and in its checkpoints, so that a continued or
    resumed run logs the same means as an uninterrupted one), the high level's choices since
    the last log, since the progress bar's last text and over the call, and the bar itself."""

    def __init__(self, model: Any, start_steps: int, total_timesteps: int, progress_bar: bool):
        self.model, self.start_steps = model, start_steps
        self.episodes = find_episode_recorder(model.env)
        self.bar = make_progress_bar(total_timesteps, "TL-AC", progress_bar)
        self.usage = np.zeros(model.n_choices)  # the choices since the bar's last text
        self.call_usage = np.zeros(model.n_choices)  # ... and in this call, for its final text
        if model._log_window is None or start_steps == 0:
            model._log_window = (
                MetricWindow(counts=("train/n_updates",)),
                np.zeros(model.n_choices),
            )
        self.window, self.logged_usage = model._log_window  # the choices since the last log
        self.sb3_output = model.sb3.output(model.verbose, model.tensorboard_log)
        self.interval = model.recorder.log_interval if model.recorder else model.log_interval
        self.next_log = next_log_step(start_steps, self.interval)
        self.t0, self.last_bar = time.time(), 0.0

    def add(self, choices: np.ndarray, summary: dict[str, float]) -> None:
        """An iteration's high-level ``choices`` (its rollout's) and its update's ``summary``."""
        counts = np.bincount(choices.reshape(-1), minlength=self.model.n_choices)
        self.usage += counts
        self.call_usage += counts
        self.logged_usage += counts
        self.window.add(summary)

    def show(self, end_steps: int) -> None:
        """Log the window when its step comes (progress.csv, and SB3's logger with
        ``verbose`` / ``tensorboard_log``) and move the progress bar."""
        model = self.model
        if (model.recorder is not None or self.sb3_output) and model.num_timesteps >= self.next_log:
            fps = (model.num_timesteps - self.start_steps) / max(time.time() - self.t0, 1e-9)
            shares = self.logged_usage / max(self.logged_usage.sum(), 1.0)
            names = [*model.teacher_names, "agent"]
            usage_metrics = {f"teacher/{n}": float(v) for n, v in zip(names, shares, strict=True)}
            metrics = self.window.flush()
            if model.advice is not None:  # the answers asked so far, per teacher
                metrics.update(model.advice.metrics(model.teacher_names))
            log_metrics(model, metrics, fps, self.episodes, self.sb3_output, usage_metrics)
            self.logged_usage[:] = 0
            self.next_log = next_log_step(model.num_timesteps, self.interval)
        if self.bar is not None:
            self.bar.update(min(model.num_timesteps, end_steps) - self.bar.n - self.start_steps)
            if time.time() - self.last_bar > 0.5:
                self.last_bar = time.time()
                self.bar.set_postfix_str(self.bar_text(self.usage), refresh=False)
                self.usage[:] = 0

    def close(self) -> None:
        """The bar's final text: the whole call's shares."""
        if self.bar is not None:
            span = f"all {self.model.num_timesteps - self.start_steps} steps:"
            self.bar.set_postfix_str(self.bar_text(self.call_usage, span), refresh=False)
            self.bar.close()

    def bar_text(self, usage: np.ndarray, span: str = "recent:") -> str:
        """The progress bar's text: the training return, the high level's choices and, where
        advice is limited (a budget, costs, availability, an asking rule), the answers asked so
        far and the budget spent (without limits they are in progress.csv and result.json)."""
        model = self.model
        text = progress_text(self.episodes, usage, model.teacher_names, span)
        if model.advice is None or not model.limited_advice:
            return text
        return f"{text} | {model.advice.progress(model.teacher_names)}"
