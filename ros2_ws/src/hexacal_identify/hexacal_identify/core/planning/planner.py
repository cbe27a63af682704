"""
Plan postures: choose the K measuring postures that best determine the model's parameters.

Measuring a posture costs machine time, so the postures are chosen, not drawn:
from a large set of feasible candidates (sphere and fixed-position postures,
section 3.2), K are picked to maximise an observability index of the
identification Jacobian (eq. 6 / 9 / 11) at the nominal parameters.  Every
architecture plans the same way: the nominal parameters name their
architecture (``params.architecture``), which supplies the IK, the
workspace check and the passive-joint angles; n below is its number of
parameters (54 for the Hexa Slide, 42 for the Gough-Stewart platform).

The steps live in their own modules: candidates within ``posture_limits.PostureLimits``
(posture_limits.py), their Jacobian rows (candidate_set.py), the indices
(observability.py) and the greedy / exchange selection (design.py); this module
orders the chosen postures (``travel_order``), names and returns the `Plan`, whose
file is read and written by hexacal_msgs_py.plan_file.

Planning for an imperfect device (``device_columns``, ``device_prior``,
``procedure``; absolute cost).  The rows gain the columns of the device
parameters identified with the machine, the information starts from the
priors' (1 / std^2 on their columns), and every sphere candidate is offered
once per device turn of the procedure (``studies.device_procedure.PROCEDURES``:
0 / 180 deg, or 0 / 90 / 180 / 270 deg), so the plan chooses which postures
to measure in which mounting.  I then predicts the position error with the
device parameters' uncertainty marginalised: W weighs the kinematic columns
only.  The plan's postures carry their ``device_turn`` and are ordered by turn
(one remount per turn), each turn's postures in a travel tour.

Planning for a measuring mode (``measuring_mode``; measuring_plan.py).
``passive_actuator`` chooses each posture's released actuator (released_actuator.py)
and, within each kind and mounting, the order, and writes them into the plan; ``lvdt``
checks every posture's predicted link extension.  With six commanded actuators
(``lvdt``, ``compliant``) the candidates are only those six stiff drives hold on
machines unlike the nominal (robust_postures.py).  The plan's fingerprint (and so its
default name) is that of its postures, in order, and turns.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import hashlib
from pathlib import Path
import time

from hexacal_msgs_py.measuring_modes import DEFAULT_LVDT_STROKE_M
from hexacal_msgs_py.models import DEFAULT_MODEL, MODELS
from hexacal_msgs_py.plan_file import (
    json_safe,
    plan_file_text,
    PlanFile,
    read_plan_file,
    write_plan_file,
)
import numpy as np

from .candidate_set import build_candidate_set, CandidateSet
from .measuring_plan import check_measuring_mode, MeasuringCheck
from .observability import check_index, INDICES, PREDICTION
from .posture_limits import default_fixed_fraction, generate_candidates, PostureLimits
from .robust_postures import hold_on_machines
from .selection import exchange_design, greedy_design, no_progress, Progress
from ..architectures import KinematicParameters
from ..fit.residuals import ChannelSigma
from ..machine.device import check_mount, DEFAULT_MOUNT, DevicePrior
from ..machine.measurements import FIXED, NoiseModel, POSTURE_KINDS, SPHERE
from ..modes.link_load import LinkLoad
from ..walk.guard import GuardSettings

# Candidates a plan may leave out, in all, for loading the link beyond its limit (link_load): a
# few planning rounds; what is left beyond is reported (MeasuringCheck.overloaded).
MAX_LEFT_OUT = 100

METHODS = ('greedy', 'exchange')


def _fingerprint(nominal: KinematicParameters) -> str:
    """Return the nominal parameters' fingerprint in a plan's metadata (16 hex digits)."""
    return hashlib.sha256(np.round(nominal.vector, 12).tobytes()).hexdigest()[:16]


def _turn_order(turns: np.ndarray | None, design: np.ndarray, order: np.ndarray) -> np.ndarray:
    """Return ``order`` (a travel order of ``design``) stably regrouped by device turn."""
    # One remount per turn.
    if turns is None:
        return order
    return order[np.argsort(turns[design][order], kind='stable')]


# Modes whose six actuators are all commanded: a posture must be one the true drives can hold.
SIX_COMMANDED = ('lvdt', 'compliant')
# The condition number a machine unlike the nominal may show at a held posture, x max_condition.
HELD_CONDITION_FACTOR = 2.0


def _held_candidates(nominal, poses, kinds, limits, n_postures, progress, extension):
    """Return the candidates six stiff drives hold on machines unlike the nominal (doc)."""
    held = hold_on_machines(
        nominal, poses, limits.link_length, HELD_CONDITION_FACTOR * limits.max_condition,
        max_extension_m=extension,
    )
    progress(
        f'{int(np.sum(held))} of {len(poses)} candidates held by six commanded drives on '
        'machines unlike the nominal'
    )
    if np.sum(held) < n_postures:
        raise ValueError(
            f'only {int(np.sum(held))} of {len(poses)} candidate postures can be held by six '
            'commanded drives on machines that differ from the nominal as one built to its '
            f'drawing does; {n_postures} are asked: narrow the workspace or plan more candidates'
        )
    return poses[held], kinds[held]


def walk_groups(kinds: np.ndarray, turns: np.ndarray | None) -> np.ndarray:
    """Return a group number per posture (plan order): a new group where kind or turn changes."""
    keys = list(zip(kinds, np.zeros(len(kinds)) if turns is None else turns))
    changes = [0] + [int(keys[i] != keys[i - 1]) for i in range(1, len(keys))]
    return np.cumsum(changes)


def travel_order(
    poses: np.ndarray, kinds: np.ndarray, link_length: float, keep_order_within_kind: bool
) -> np.ndarray:
    """
    Return the plan order: sphere postures first, then fixed ones (section 3.2's procedure).

    Within a kind a nearest-neighbour tour (angles weighted by L) shortens the moves, unless
    the order must stay.
    """
    order = []
    for kind in POSTURE_KINDS:
        members = np.flatnonzero(kinds == kind)
        if keep_order_within_kind or len(members) < 3:
            order.extend(members.tolist())
            continue
        weighted = np.column_stack([poses[members, :3], poses[members, 3:6] * link_length])
        remaining = list(range(len(members)))
        current = int(np.argmin(np.linalg.norm(weighted[:, :2], axis=1)))  # start near the centre
        tour = [current]
        remaining.remove(current)
        while remaining:
            distance = np.linalg.norm(weighted[remaining] - weighted[current], axis=1)
            current = remaining[int(np.argmin(distance))]
            tour.append(current)
            remaining.remove(current)
        order.extend(members[tour].tolist())
    return np.array(order, dtype=int)


@dataclass
class Plan:
    """
    Hold the planned postures (m, rad) and the planner's metadata; read and written as a plan file.

    The file format has one owner, hexacal_msgs_py.plan_file (what the driver and
    the executor read too).  ``model`` names the machine model the postures were
    planned for, ``mount`` the device mount; the metadata rides in the file's
    ``# hexacal-plan:`` comment with the plan's fingerprint, and the default name
    ends with that fingerprint, so a bag that records the plan name says exactly
    which postures it followed.  ``device_turns`` (rad, written only where
    non-zero): the device turned about its link axis for the posture (a turning
    procedure, module doc); postures without one are taken in the normal mounting.
    """

    name: str
    link_length: float
    poses: np.ndarray
    kinds: np.ndarray
    metadata: dict = field(default_factory=dict)
    model: str = DEFAULT_MODEL
    mount: str = DEFAULT_MOUNT
    device_turns: np.ndarray | None = (
        None  # (K,) rad per posture; None = every posture in the normal mounting
    )
    measuring_mode: str | None = None  # None: not written (the reader's default)
    # (K,) actuator joint names (passive_actuator mode) or None per posture; None: not written.
    released_actuators: tuple[str | None, ...] | None = None

    def __post_init__(self) -> None:
        self.poses = np.atleast_2d(np.asarray(self.poses, dtype=float)).reshape(-1, 6)
        if self.device_turns is not None:
            self.device_turns = np.asarray(self.device_turns, dtype=float).reshape(-1)
            if self.device_turns.shape != (len(self.poses),) or not np.all(
                np.isfinite(self.device_turns)
            ):
                raise ValueError(
                    'plan device_turn: one finite angle (rad) per posture, got '
                    f'{self.device_turns!r}'
                )
            if not np.any(self.device_turns):
                self.device_turns = None
        self.kinds = np.asarray(self.kinds).astype(str).reshape(-1)
        if not isinstance(self.name, str) or not self.name.strip():
            raise ValueError('plan name must be a non-empty string')
        if len(self.kinds) != len(self.poses) or not len(self.poses):
            raise ValueError(
                f'plan needs postures and one kind each: {len(self.poses)} poses, '
                f'{len(self.kinds)} kinds'
            )
        unknown = sorted(set(self.kinds) - set(POSTURE_KINDS))
        if unknown:
            raise ValueError(f'unknown posture kind(s) {unknown}; expected one of {POSTURE_KINDS}')
        if not np.all(np.isfinite(self.poses)):
            raise ValueError('plan poses must be finite numbers')
        if not (np.isfinite(self.link_length) and self.link_length > 0):
            raise ValueError(
                f'plan link_length must be a positive length in m, got {self.link_length}'
            )
        if self.model not in MODELS:
            raise ValueError(
                f'plan model {self.model!r} is not a machine model hexacal knows '
                f'({", ".join(sorted(MODELS))})'
            )
        check_mount(self.mount)

    def __len__(self) -> int:
        return len(self.poses)

    @property
    def turns(self) -> np.ndarray:
        """(K,) device turn per posture, rad (zeros when none is turned)."""
        return self.device_turns if self.device_turns is not None else np.zeros(len(self.poses))

    def fingerprint(self) -> str:
        """
        Return the first 8 hex digits of the sha256 of kinds, poses and device turns.

        Poses and turns to 1e-12: the fingerprint names the postures.
        """
        text = ';'.join(
            f'{k}:' + ','.join(f'{v:.12e}' for v in pose) + (f'@{turn:.12e}' if turn else '')
            for k, pose, turn in zip(self.kinds, self.poses, self.turns)
        )
        return hashlib.sha256(text.encode()).hexdigest()[:8]

    def plan_file(self) -> PlanFile:
        """Return the plan-file contents: metadata with the fingerprint, turns only where set."""
        return PlanFile(
            self.name,
            float(self.link_length),
            self.poses,
            tuple(self.kinds),
            self.model,
            self.mount,
            tuple(float(turn) if turn else None for turn in self.turns),
            dict(json_safe(self.metadata), fingerprint=self.fingerprint()),
            measuring_mode=self.measuring_mode,
            released_actuators=tuple(self.released_actuators or ()),
        )

    def to_text(self) -> str:
        """Return the plan file's text (hexacal_msgs_py.plan_file)."""
        return plan_file_text(self.plan_file())

    def save(self, path: Path | str) -> Path:
        """Write atomically (temporary file in the same directory, fsync, rename)."""
        return write_plan_file(path, self.plan_file())

    @classmethod
    def load(cls, path: Path | str) -> 'Plan':
        """Read a plan file (hexacal_msgs_py.plan_file; its PlanError is a ValueError)."""
        contents = read_plan_file(path)
        metadata = dict(contents.metadata or {})
        metadata.pop('fingerprint', None)
        return cls(
            contents.name,
            contents.link_length,
            contents.poses.copy(),
            np.array(contents.kinds),
            metadata,
            contents.model,
            contents.mount,
            np.array([contents.device_turn(i) for i in range(len(contents))]),
            contents.measuring_mode,
            contents.released_actuators or None,
        )


@dataclass
class PlanningResult:
    plan: Plan
    candidates: CandidateSet
    design: np.ndarray  # candidate indices, in plan order
    selection_order: np.ndarray  # the same indices in the order greedy / exchange chose them
    indices: dict[
        str, float
    ]  # O1..O4 of the plan, and I: its predicted RMS position error (see CandidateSet)
    rank: int  # of its identification Jacobian: below the model's parameter count every index is 0
    greedy_history: list[float]
    exchange_history: list[float]
    candidate_seconds: float
    selection_seconds: float
    measuring: MeasuringCheck | None = None  # the measuring mode's additions (None: no mode)
    measuring_seconds: float = 0.0  # its check: passive_actuator, the release rehearsal

    def random_indices(self, draws: int = 20, seed: int = 0) -> dict[str, float]:
        """Return the mean O1..O4 and I of random plans of this size and kind mix."""
        rng = np.random.default_rng(seed)
        kinds = self.candidates.kinds
        counts = {k: int(np.sum(self.plan.kinds == k)) for k in POSTURE_KINDS}
        designs = [
            np.concatenate(
                [
                    rng.choice(np.flatnonzero(kinds == k), c, replace=False)
                    for k, c in counts.items()
                    if c
                ]
            )
            for _ in range(draws)
        ]
        values = [self.candidates.indices(design) for design in designs]
        errors = [self.candidates.predicted_position_error(d) for d in designs]
        means = {name: float(np.mean([v[name] for v in values])) for name in INDICES}
        means[PREDICTION] = float(np.mean(errors))
        return means


MARGIN_REDRAWS = 10  # draws that replace candidates short of the model-change margin


def _model_margin_candidates(nominal, poses, kinds, limits, rng, model_error_m):
    """
    Return the candidates, each keeping the model-change margin (model_margin.py).

    A candidate short of it is replaced by a fresh draw of its kind from the same generator, so
    the count and kind split stay those asked for; the others are unchanged.
    """
    from ..modes.release_rehearsal import model_error_rms_m
    from .model_margin import keep_model_margin

    error_m = model_error_rms_m(nominal) if model_error_m is None else float(model_error_m)
    if error_m == 0:
        return poses, kinds
    stroke = limits.actuator_stroke_m
    keep = keep_model_margin(nominal, poses, stroke, error_m)
    if keep.all():
        return poses, kinds
    parts, part_kinds = [], []
    for kind, fixed_fraction in ((SPHERE, 0.0), (FIXED, 1.0)):
        wanted = int(np.sum(kinds == kind))
        if not wanted:
            continue
        kept = poses[(kinds == kind) & keep]
        for _ in range(MARGIN_REDRAWS):
            if len(kept) >= wanted:
                break
            extra, _ = generate_candidates(nominal, 2 * (wanted - len(kept)) + 16, rng, limits,
                                           fixed_fraction)
            kept = np.concatenate([kept, extra[keep_model_margin(nominal, extra, stroke,
                                                                 error_m)]])
        else:
            raise ValueError(
                f'could not find {wanted} {kind} candidate postures whose targets stay inside '
                f'the stroke {tuple(stroke)} m less the margin a model error of '
                f'{error_m * 1e3:g} mm RMS needs (a smaller model error, or a wider stroke)'
            )
        parts.append(kept[:wanted])
        part_kinds.append(np.full(wanted, kind))
    return np.concatenate(parts), np.concatenate(part_kinds)


# What `stage` hears as a measuring mode's check begins.
_MEASURING_STAGES = {'passive_actuator': 'rehearsal of the releases'}


def progress_steps(
    n_postures: int, method: str = METHODS[0], measuring_mode: str | None = None
) -> int:
    """Return how many steps ``plan_postures`` reports to its ``progress`` (a display's total)."""
    steps = n_postures * (2 if method == 'exchange' else 1) + 1
    if measuring_mode == 'passive_actuator':
        steps += n_postures  # each posture rehearsed
    return steps


def plan_postures(
    nominal: KinematicParameters,
    n_postures: int,
    *,
    index: str = 'O1',
    method: str = METHODS[0],
    n_candidates: int = 2000,
    cost: str = 'absolute',
    limits: PostureLimits | None = None,
    fixed_fraction: float | None = None,
    seed: int = 0,
    sigma: ChannelSigma = ChannelSigma(),
    noise: NoiseModel | None = None,
    name: str | None = None,
    progress: Progress = no_progress,
    stage: Progress = no_progress,
    device_columns: tuple[str, ...] = (),
    device_prior: DevicePrior = DevicePrior(),
    device_turns: tuple[float, ...] = (0.0,),
    measuring_mode: str | None = None,
    lvdt_stroke_m: float = DEFAULT_LVDT_STROKE_M,
    model_error_m: float | None = 0.0,
    link_load: LinkLoad | None = None,
) -> PlanningResult:
    """
    Candidates -> Jacobian rows at ``nominal`` -> greedy (and exchange) selection -> ordered Plan.

    ``nominal`` names its architecture; ``limits`` None = ``PostureLimits.for_machine(nominal)``.
    ``progress`` hears of each step (a candidate chosen, a posture rehearsed), ``stage`` of each
    stage begun (candidates, selection, the measuring mode's check).
    ``device_columns`` / ``device_prior``: device parameters identified with the machine (module
    doc);
    ``device_turns``: the mountings of a turning procedure, each sphere candidate offered in each.
    ``measuring_mode``: written into the plan with what it adds (module doc); None: neither.
    ``link_load``: the weights and the link's limit (passive_actuator): a posture whose chosen
    release would load the link beyond it is left out and the postures are chosen again (at
    most ``MAX_LEFT_OUT`` in all; the plan reports any left beyond the limit).
    ``model_error_m``: the RMS parameter error of the nominal, from which the stroke margin a
    posture keeps for the model change before its targets are walked (model_margin.py); None:
    the architecture's Table 2 set 2 RMS; 0 (the default): no margin. Not yet the default: the
    margin changes which postures and releases a plan takes, and the passive system's
    rehearsal does not yet keep every such plan off a fold on the true machine.
    """
    check_index(index)
    if limits is None:
        limits = PostureLimits.for_machine(nominal)
    if method not in METHODS:
        raise ValueError(f'unknown planning method {method!r}; choose one of {", ".join(METHODS)}')
    if n_postures < 1:
        raise ValueError(f'--postures must be positive, got {n_postures}')
    if n_candidates < n_postures:
        raise ValueError(
            f'need at least as many candidates ({n_candidates}) as postures ({n_postures})'
        )
    stage('candidates')
    started = time.perf_counter()
    fraction = default_fixed_fraction(cost) if fixed_fraction is None else fixed_fraction
    device = limits.device()
    rng = np.random.default_rng([seed, 0x91A4])
    poses, kinds = generate_candidates(nominal, n_candidates, rng, limits, fraction)
    poses, kinds = _model_margin_candidates(nominal, poses, kinds, limits, rng, model_error_m)
    if measuring_mode is not None and measuring_mode in SIX_COMMANDED:
        extension = (
            lvdt_stroke_m - GuardSettings().lvdt_margin_m if measuring_mode == 'lvdt' else np.inf
        )
        poses, kinds = _held_candidates(
            nominal, poses, kinds, limits, n_postures, progress, extension
        )
    turns = None
    if len(device_turns) > 1 or any(device_turns):  # every sphere candidate in every mounting
        sphere = kinds == SPHERE
        turns = np.concatenate(
            [
                np.repeat(np.asarray(device_turns, float), int(sphere.sum())),
                np.zeros(int((~sphere).sum())),
            ]
        )
        poses = np.concatenate([np.tile(poses[sphere], (len(device_turns), 1)), poses[~sphere]])
        kinds = np.concatenate([np.tile(kinds[sphere], len(device_turns)), kinds[~sphere]])
    left_out = 0  # candidates left out for the link's load (link_load)
    measuring_seconds = 0.0
    while True:
        progress(f'{len(poses)} candidates')
        candidates = build_candidate_set(
            nominal,
            poses,
            kinds,
            cost,
            device,
            sigma,
            noise,
            tuple(device_columns),
            device_prior,
            turns,
        )
        candidate_seconds = time.perf_counter() - started
        stage('selection')
        started = time.perf_counter()
        kind_counts = None
        if (
            cost == 'relative'
        ):  # the paper's 3 sphere : 1 fixed (60 + 20, 30 + 10), as study.posture_split
            fixed = max(n_postures // 4, 1) if np.any(kinds == FIXED) else 0
            kind_counts = {SPHERE: n_postures - fixed, FIXED: fixed}
        design, greedy_history = greedy_design(
            candidates, n_postures, index, progress, kind_counts
        )
        exchange_history: list[float] = []
        if method == 'exchange':
            design, exchange_history = exchange_design(
                candidates, design, index, progress=progress
            )
        selection_seconds = time.perf_counter() - started
        selection_order = design.copy()
        order = _turn_order(
            turns,
            design,
            travel_order(
                poses[design],
                kinds[design],
                limits.link_length,
                keep_order_within_kind=cost == 'relative',
            ),
        )
        design = design[order]
        indices = candidates.indices(design)
        indices[PREDICTION] = candidates.predicted_position_error(design)
        rank = candidates.rank(design)
        actuator = nominal.layout.actuator_prefix
        weighting = (
            'none'
            if noise is None
            else (
                f'noise {actuator} {noise.actuator_m:g} {nominal.layout.actuator_unit}, angles '
                f'{noise.angle_rad:g} rad'
            )
        )
        metadata = {
            'planner': 'hexacal plan',
            'model': nominal.model,
            'index': index,
            'index_value': indices[index],
            'rank': rank,
            'method': method,
            'cost': cost,
            'weighting': weighting,
            'candidates': int(len(poses)),
            'seed': int(seed),
            'nominal_fingerprint': _fingerprint(nominal),
            'limits': limits.to_json(),
        }
        if turns is not None or candidates.device_columns:
            metadata.update(
                device_columns=list(candidates.device_columns),
                device_turns=list(device_turns),
                device_prior={n: {'value': v, 'std': sd} for n, v, sd in device_prior.entries},
            )
        measuring = None
        if measuring_mode is not None:
            # The order within each kind and mounting is free unless the cost pairs consecutive
            # postures: the passive-actuator check may choose it (released_actuator.py).
            groups = None if cost == 'relative' else walk_groups(
                kinds[design], None if turns is None else turns[design]
            )
            stage(_MEASURING_STAGES.get(measuring_mode, f'{measuring_mode} check'))
            checking = time.perf_counter()
            measuring = check_measuring_mode(
                nominal,
                poses[design],
                limits.link_length,
                limits.actuator_stroke_m,
                measuring_mode,
                lvdt_stroke_m,
                limits.mount,
                groups,
                link_load,
                progress,
            )
            measuring_seconds += time.perf_counter() - checking
            if measuring.release is not None and measuring.release.order is not None:
                design = design[measuring.release.order]
        over = np.zeros(0, int) if measuring is None else measuring.overloaded
        if not over.size or len(poses) - over.size < n_postures or left_out >= MAX_LEFT_OUT:
            break
        # Plan again without the postures whose release loads the link beyond its limit:
        # the releases are chosen for the passive system's conditioning along the moves.
        keep = np.ones(len(poses), bool)
        keep[design[over]] = False
        left_out += int(over.size)
        poses, kinds = poses[keep], kinds[keep]
        turns = None if turns is None else turns[keep]
    if measuring is not None and measuring.link_force_limit_n is not None:  # link_load given
        metadata['link_force_limit_n'] = measuring.link_force_limit_n
        metadata['link_overloaded_left_out'] = left_out
    plan = Plan(
        name or 'plan',
        limits.link_length,
        poses[design],
        kinds[design],
        metadata,
        nominal.model,
        limits.mount,
        None if turns is None else turns[design],
    )
    if name is None:  # default name: what it is and which postures
        plan.name = f'{method}-{index}-{n_postures}-{plan.fingerprint()}'
    if measuring is not None:
        plan.measuring_mode = measuring.mode.value
        if measuring.release is not None:
            plan.released_actuators = measuring.release.names(nominal.layout.actuator_names)
    return PlanningResult(
        plan,
        candidates,
        design,
        selection_order,
        indices,
        rank,
        greedy_history,
        exchange_history,
        candidate_seconds,
        selection_seconds,
        measuring,
        measuring_seconds,
    )


__all__ = [
    'METHODS',
    'Plan',
    'PlanningResult',
    'plan_postures',
    'progress_steps',
    'travel_order',
]
