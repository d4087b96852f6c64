"""Scenes: TOML files naming a model, its parameters, switches and perturbations (shipped in scenes/ or a path)."""

from __future__ import annotations

import dataclasses
import math
import tomllib
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

from protocol import codec

from .accuracy import DEFAULT, check_level
from .models import model_names
from .models.options import (
    _PERT_KEYS,
    FAULT_KINDS,
    ConfigError,
    Fault,
    ImageOptions,
    ModelOptions,
    NoiseOptions,
    Perturbation,
    parse_fault,
    parse_options,
    parse_perturbation,
)
from .params import REACTION_KEYS, Params
from .topology import Topology, TopologyError

SCENE_DIR = Path(__file__).resolve().parent / "scenes"
TOP_KEYS = (
    "name",
    "description",
    "model",
    "cells",
    "lattice",
    "boundary",
    "t_end_s",
    "accuracy",
    "question",
    "params",
    "model_options",
    "perturbation",
    "fault",
)
LIST_KEYS = ("perturbation", "fault")  # arrays of tables: --set perturbation.N.field, fault.N.field
REQUIRED = ("name", "model", "cells", "t_end_s")
TOPOLOGY_KEYS = ("shape", "lattice", "boundary")  # Params fields a scene sets through cells, lattice, boundary
CHAIN_MAX = 4096  # cells of a chain
SHEET_MAX = 65536  # cells of a sheet (256 x 256, the largest shipped sheet)
IMAGE_BOARDS_MAX = 16  # cell boards of the image tier: the rig's bus (a sheet or ring of up to 16 runs there)


@dataclass(frozen=True)
class Scene:
    name: str
    description: str
    model: str
    cells: int  # the number of cells (rows * cols on a sheet); the lattice itself: .topology
    t_end_s: float
    params: Params
    options: ModelOptions = field(default_factory=ModelOptions)
    perturbations: tuple[Perturbation, ...] = ()
    source: str = ""
    accuracy: str = "balanced"  # fast | balanced | exact (host_emulator/accuracy.py)
    explicit_options: tuple[str, ...] = ()  # model_options keys the scene set itself (they beat the preset)
    faults: tuple[Fault, ...] = ()  # image model only ([[fault]])
    question: str = ""  # what the scene is for (host_emulator/tiers.py QUESTIONS), "" if it does not say
    model_reason: str = ""  # model = "auto": the one line saying which tier was picked and why

    @property
    def topology(self) -> Topology:
        """The lattice of the scene (a chain of `cells`, a ring, or a sheet): params.topology."""
        return self.params.topology

    def topology_record(self) -> dict:
        """`cells` as the scene gave it (n, or [rows, cols]) and, unless the scene is the open chain every older
        scene is, `lattice` and `boundary` (an older scene's record stays as it was; so do its params, while any
        other lattice's params also carry shape, lattice and boundary: summary.json's params name the lattice)."""
        t = self.topology
        if t.is_open_chain:
            return {"cells": self.cells}
        return {"cells": t.cells_spec, "lattice": t.kind, "boundary": t.boundary}

    def as_dict(self) -> dict:
        """JSON-ready record of everything the run used."""
        opts = dataclasses.asdict(self.options)
        params = dataclasses.asdict(self.params)
        if self.topology.is_open_chain:  # an open chain's record as before Params knew its lattice
            params = {k: v for k, v in params.items() if k not in TOPOLOGY_KEYS}
        return {
            "name": self.name,
            "description": self.description,
            "model": self.model,
            **self.topology_record(),
            "t_end_s": self.t_end_s,
            "params": {k: list(v) if isinstance(v, tuple) else v for k, v in params.items()},
            "model_options": opts,
            "perturbation": [p.as_dict() for p in self.perturbations],
            "fault": [f.as_dict() for f in self.faults],
            "source": self.source,
            "accuracy": self.accuracy,
        }


def did_you_mean(word: str, choices: Iterable[str]) -> str:
    """' (did you mean X?)' for the closest of choices, or ''."""
    import difflib

    m = difflib.get_close_matches(str(word), [str(c) for c in choices], n=1, cutoff=0.6)
    return f" (did you mean {m[0]!r}?)" if m else ""


def list_scenes() -> list[tuple[str, str, str]]:
    """(name, model, description) of every shipped scene."""
    out = []
    for f in sorted(SCENE_DIR.glob("*.toml")):
        with open(f, "rb") as fh:
            d = tomllib.load(fh)
        out.append((f.stem, d.get("model", "?"), d.get("description", "")))
    return out


def _parse_params(d, cells, topology: Topology | None = None) -> Params:
    """[params] of a scene of `cells` cells on `topology` (None: the open chain of `cells`)."""
    if not isinstance(d, dict):
        raise ConfigError("params: expected a table")
    base = Params()
    types = {f.name: f.type for f in dataclasses.fields(Params) if f.name not in TOPOLOGY_KEYS}
    kw: dict = {"cells": cells}
    if topology is not None:
        kw.update(shape=topology.shape if topology.is_sheet else (), lattice=topology.kind)
        kw["boundary"] = topology.boundary
    for k, v in d.items():
        key = f"params.{k}"
        if k == "cells" or k in TOPOLOGY_KEYS:
            top = "cells" if k in ("cells", "shape") else k
            raise ConfigError(f"params.{k}: set the top-level `{top}` key instead")
        if k not in types:
            raise ConfigError(
                f"unknown key {key}{did_you_mean(k, types) or key_hint(k)}; "
                f"known: {', '.join(sorted(n for n in types if n != 'cells'))}"
            )
        cur = getattr(base, k)
        if k in REACTION_KEYS and isinstance(v, list):
            kw[k] = _per_cell_list(key, v, cells, topology)
            continue
        if isinstance(cur, bool):
            if not isinstance(v, bool):
                raise ConfigError(f"{key} = {v!r}: expected true or false")
        elif isinstance(cur, int):
            if isinstance(v, bool) or not isinstance(v, int):
                raise ConfigError(f"{key} = {v!r}: expected an integer")
        else:
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ConfigError(f"{key} = {v!r}: expected a finite number")
            v = float(v)
        kw[k] = v
    p = base.with_overrides(**kw)
    for k in (
        "I_a",
        "I_b",
        "eta_a",
        "gamma",
        "eta_scale",
        "k_a",
        "k_b",
        "supply_v",
        "vmax_v",
        "kt",
        "speed_const",
        "control_rate_hz",
    ):
        if not getattr(p, k) > 0:
            raise ConfigError(f"params.{k} = {getattr(p, k)!r}: must be > 0")
    for j, a in enumerate(p.per_cell("alpha_star")):
        if a < 0:
            per = "alpha_star" in p.per_cell_keys
            where = f"params.alpha_star[{j + 1}] (cell {j + 1})" if per else "params.alpha_star"
            raise ConfigError(f"{where} = {float(a)!r}: must be >= 0")
    return p


def _per_cell_list(key: str, v: list, cells: int, topology: Topology | None = None) -> tuple[float, ...]:
    """A reaction parameter given one value per cell: a list of `cells` finite numbers (cell 1 first, a sheet's row
    by row), or on a sheet a list of its rows (rows lists of cols numbers)."""
    if topology is not None and topology.is_sheet and v and all(isinstance(r, list) for r in v):
        rows, cols = topology.shape
        if len(v) != rows:
            raise ConfigError(f"{key}: {len(v)} rows for a sheet of {rows} rows; give one list of {cols} per row")
        for i, r in enumerate(v):
            if len(r) != cols:
                raise ConfigError(f"{key}[{i + 1}] (row {i + 1}): {len(r)} values for {cols} columns")
        for i, r in enumerate(v):
            for c, x in enumerate(r):
                if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
                    raise ConfigError(
                        f"{key}[{i + 1}][{c + 1}] (row {i + 1}, col {c + 1}) = {x!r}: expected a finite number"
                    )
        return tuple(float(x) for r in v for x in r)
    if len(v) != cells:
        raise ConfigError(
            f"{key}: {len(v)} values for {cells} cells; give one number, or one per cell (a list of {cells})"
        )
    out = []
    for j, x in enumerate(v):
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
            raise ConfigError(f"{key}[{j + 1}] (cell {j + 1}) = {x!r}: expected a finite number")
        out.append(float(x))
    return tuple(out)


def known_keys() -> list[str]:
    """Every dotted key a --set / overrides item can name (perturbation fields as perturbation.N.<field>)."""
    keys = [k for k in TOP_KEYS if k not in ("params", "model_options", *LIST_KEYS)]
    keys += [f"params.{f.name}" for f in dataclasses.fields(Params) if f.name not in ("cells", *TOPOLOGY_KEYS)]
    for f in dataclasses.fields(ModelOptions):
        if f.name == "noise":
            keys += [f"model_options.noise.{g.name}" for g in dataclasses.fields(NoiseOptions)]
        elif f.name == "image":
            keys += [f"model_options.image.{g.name}" for g in dataclasses.fields(ImageOptions)]
        else:
            keys.append(f"model_options.{f.name}")
    keys += [f"perturbation.N.{k}" for k in (*_PERT_KEYS, "row", "col")]
    fault_keys = {"kind", "start_s", "cell", "row", "col"} | {k for _, takes in FAULT_KINDS.values() for k in takes}
    keys += [f"fault.N.{k}" for k in sorted(fault_keys)]
    return keys


def key_hint(key: str) -> str:
    """' (did you mean params.sigma?)' for a bare or misspelt key: the dotted keys ending in it, else the closest."""
    key = str(key)
    known = known_keys()
    ends = [k for k in known if k.endswith("." + key)]
    if ends:
        return f" (did you mean {' or '.join(ends)}?)"
    return did_you_mean(key, known)


def scene_table(scene: Scene) -> dict:
    """A Scene back as the table scene_from_dict reads (what a TOML file holds): every parameter, the model options
    the scene set itself (the others stay free for its accuracy preset), the perturbations. JSON-ready."""
    d = scene.as_dict()
    params = {k: v for k, v in d["params"].items() if k not in ("cells", *TOPOLOGY_KEYS)}
    opts = {k: d["model_options"][k] for k in scene.explicit_options}
    return {
        "name": scene.name,
        "description": scene.description,
        "model": scene.model,
        **scene.topology_record(),
        "t_end_s": scene.t_end_s,
        "accuracy": scene.accuracy,
        **({"question": scene.question} if scene.question else {}),
        "params": params,
        "model_options": opts,
        "perturbation": d["perturbation"],
        **({"fault": [_fault_table(f) for f in scene.faults]} if scene.faults else {}),
    }


def _fault_table(f: Fault) -> dict:
    """A Fault back as its [[fault]] table (only the keys its kind takes)."""
    takes = FAULT_KINDS[f.kind][1]
    out: dict = {"kind": f.kind, "start_s": f.start_s}
    if "cell" in takes:
        out["cell"] = int(f.board[4:])
    if "board" in takes:
        out["board"] = f.board
    for k in ("duration_s", "chain", "rate_hz"):
        if k in takes:
            out[k] = getattr(f, k)
    return out


def scene_from_dict(d: dict, source: str = "") -> Scene:
    """Validate a scene table; ConfigError names the first bad key."""
    if not isinstance(d, dict):
        raise ConfigError("scene: expected a table")
    for k in d:
        if k not in TOP_KEYS:
            raise ConfigError(f"unknown key {k!r}{key_hint(k)}; known: {', '.join(TOP_KEYS)}")
    for k in REQUIRED:
        if k not in d:
            raise ConfigError(f"missing key {k!r}")
    if not isinstance(d["name"], str) or not d["name"]:
        raise ConfigError(f"name = {d['name']!r}: expected a non-empty string")
    desc = d.get("description", "")
    if not isinstance(desc, str):
        raise ConfigError(f"description = {desc!r}: expected a string")
    from .tiers import check_question, pick, question_of

    question = check_question(d["question"]) if "question" in d else ""
    model, reason = d["model"], ""
    if model == "auto":  # the cheapest tier that models the scene's question
        question = question_of(d)
        model, reason = pick(question)
    elif model not in model_names():
        raise ConfigError(f"model = {model!r}: expected one of {', '.join(model_names())} or auto")
    topo = parse_topology(d)
    cells = topo.n
    if model == "image" and not topo.is_open_chain and topo.n > IMAGE_BOARDS_MAX:
        raise ConfigError(
            f"model = 'image' with cells = {topo.cells_spec!r}: the image tier runs the rig's {IMAGE_BOARDS_MAX} cell "
            f"boards on one bus, not {topo.n} (a {topo.describe()} runs on lattice or hil)"
        )
    t_end = d["t_end_s"]
    if isinstance(t_end, bool) or not isinstance(t_end, (int, float)) or not (math.isfinite(t_end) and t_end > 0):
        raise ConfigError(f"t_end_s = {t_end!r}: expected a positive number")
    params = _parse_params(d.get("params", {}), cells, topo)
    options = parse_options(d.get("model_options", {}))
    perts = d.get("perturbation", [])
    if isinstance(perts, dict):
        perts = [perts]
    if not isinstance(perts, list):
        raise ConfigError("perturbation: expected [[perturbation]] tables")
    where = topo if topo.is_sheet else cells  # a sheet's pushes may say row and col
    perturbations = tuple(parse_perturbation(p, where, f"perturbation[{i + 1}]") for i, p in enumerate(perts))
    if model == "hil" and options.perturb_via == "firmware":
        for i, p in enumerate(perturbations):
            if abs(codec.si_to_raw("uN*m", p.torque_Nm)) > codec.LIMITS["PERTURB_MAX_UNM"]:
                raise ConfigError(
                    f"perturbation[{i + 1}].torque_Nm = {p.torque_Nm}: the firmware accepts at most "
                    f"{codec.PERTURB_MAX_NM:g} N*m"
                )
    faults_in = d.get("fault", [])
    if isinstance(faults_in, dict):
        faults_in = [faults_in]
    if not isinstance(faults_in, list):
        raise ConfigError("fault: expected [[fault]] tables")
    if faults_in and model != "image":
        raise ConfigError(f"fault: only the image model injects faults into boards (model = {model!r})")
    faults = tuple(parse_fault(f, where, f"fault[{i + 1}]") for i, f in enumerate(faults_in))
    accuracy = check_level(d.get("accuracy", DEFAULT))
    explicit = tuple(d.get("model_options", {}).keys())
    return Scene(
        d["name"],
        desc,
        model,
        cells,
        float(t_end),
        params,
        options,
        perturbations,
        source,
        accuracy,
        explicit,
        faults,
        question,
        reason,
    )


def parse_topology(d: dict) -> Topology:
    """The lattice of a scene table: `cells` (n for a chain, [rows, cols] for a sheet), `lattice` ("square" or
    "hex"; a sheet's, default square) and `boundary` ("open" or "periodic": a periodic chain is a ring). A bad value
    is a ConfigError naming the key (the TopologyError's one line)."""
    cells, lattice, boundary = d["cells"], d.get("lattice"), d.get("boundary", "open")
    if lattice is not None and not isinstance(lattice, str):
        raise ConfigError(f"lattice = {lattice!r}: expected one of square, hex (a sheet's) or chain")
    if not isinstance(boundary, str):
        raise ConfigError(f"boundary = {boundary!r}: expected open or periodic")
    if (
        isinstance(cells, list)
        and len(cells) == 2
        and all(isinstance(c, int) and not isinstance(c, bool) for c in cells)
    ):
        if cells[0] * cells[1] > SHEET_MAX:
            raise ConfigError(f"cells = {cells}: {cells[0] * cells[1]} cells; a sheet holds at most {SHEET_MAX}")
    elif isinstance(cells, list):
        raise ConfigError(f"cells = {cells!r}: expected a whole number (a chain) or [rows, cols] (a sheet)")
    elif isinstance(cells, bool) or not isinstance(cells, int) or not 1 <= cells <= CHAIN_MAX:
        raise ConfigError(f"cells = {cells!r}: expected an integer in 1..{CHAIN_MAX} (a chain) or [rows, cols]")
    try:
        t = Topology.from_spec(cells, lattice, boundary)
    except TopologyError as e:
        raise ConfigError(str(e)) from None
    return t


def _value(text: str):
    """A --set value: TOML scalar (true, 0.048, "x", 12), a fraction like 9/125, or a bare string."""
    s = text.strip()
    if "/" in s and not s.startswith(('"', "'")):
        num, den = s.split("/", 1)
        try:
            return float(num) / float(den)
        except (ValueError, ZeroDivisionError):
            raise ConfigError(f"{text!r}: not a number or fraction") from None
    try:
        return tomllib.loads(f"v = {s}")["v"]
    except tomllib.TOMLDecodeError:
        return s


def apply_overrides(d: dict, items: Iterable[str]) -> dict:
    """Apply KEY=VALUE (dotted keys: params.sigma, model_options.noise.seed, perturbation.1.torque_Nm, t_end_s;
    params.sigma.8 sets cell 8's own value of a reaction parameter, the others keeping theirs)."""
    import copy

    d = copy.deepcopy(d)
    for item in items or []:
        if "=" not in item:
            raise ConfigError(f"--set {item!r}: expected KEY=VALUE")
        key, val = item.split("=", 1)
        parts = key.strip().split(".")
        if len(parts) == 3 and parts[0] == "params" and parts[1] in REACTION_KEYS and parts[2].lstrip("-").isdigit():
            _set_cell_value(d, parts[1], int(parts[2]), _value(val), key.strip())
            continue
        node = d
        for i, part in enumerate(parts[:-1]):
            if part in LIST_KEYS and node is d:
                lst = node.setdefault(part, [])
                if isinstance(lst, dict):
                    lst = node[part] = [lst]
                if i + 1 >= len(parts) - 1 or not parts[i + 1].isdigit():
                    raise ConfigError(f"--set {key}: use {part}.N.field (N = 1..{len(lst) + 1})")
                continue
            if part.isdigit() and i > 0 and parts[i - 1] in LIST_KEYS and node is d:
                name = parts[i - 1]
                lst = node[name]
                k = int(part)
                if k == 0:
                    raise ConfigError(f"--set {key}: {name}s are numbered from 1 ({name}.1 .. {name}.{len(lst)})")
                if k == len(lst) + 1 and name == "fault":
                    lst.append({})  # fault.N.kind=... with N one past the last adds a fault
                if not 1 <= k <= len(lst):
                    raise ConfigError(f"--set {key}: the scene has {len(lst)} {name}(s)")
                node = lst[k - 1]
                continue
            nxt = node.setdefault(part, {})
            if not isinstance(nxt, dict):
                raise ConfigError(f"--set {key}: {part!r} is not a table")
            node = nxt
        node[parts[-1]] = _value(val)
        if len(parts) == 3 and parts[0] in LIST_KEYS:  # a push's place given anew replaces the old one
            for old in ("row", "col") if parts[-1] == "cell" else ("cell",) if parts[-1] in ("row", "col") else ():
                node.pop(old, None)
    return d


def _set_cell_value(d: dict, name: str, j: int, value, key: str) -> None:
    """params.<name>.<j> = value: cell j's own value (a scalar parameter becomes one value per cell first)."""
    cells = d.get("cells")
    if (
        isinstance(cells, list)
        and len(cells) == 2
        and all(isinstance(c, int) and not isinstance(c, bool) for c in cells)
    ):
        cells = cells[0] * cells[1]  # a sheet: cell j of its row-major numbering
    if isinstance(cells, bool) or not isinstance(cells, int) or cells < 1:
        raise ConfigError(f"--set {key}: the scene needs an integer `cells` (or [rows, cols]) first")
    if not 1 <= j <= cells:
        raise ConfigError(f"--set {key}: cell {j} outside 1..{cells}")
    params = d.setdefault("params", {})
    if not isinstance(params, dict):
        raise ConfigError(f"--set {key}: 'params' is not a table")
    cur = params.get(name, getattr(Params(), name))
    if isinstance(cur, list) and cur and all(isinstance(r, list) for r in cur):
        cur = [x for r in cur for x in r]  # a sheet's rows, flattened row by row
    vals = list(cur) if isinstance(cur, (list, tuple)) else [cur] * cells
    if len(vals) != cells:
        raise ConfigError(f"--set {key}: params.{name} holds {len(vals)} values for {cells} cells")
    vals[j - 1] = value
    params[name] = vals


def resolve(name_or_path: str) -> Path:
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.exists():
        if not p.is_file():
            raise ConfigError(f"scene file {name_or_path!r} not found")
        return p
    f = SCENE_DIR / f"{name_or_path}.toml"
    if not f.is_file():
        names = ", ".join(n for n, _, _ in list_scenes())
        hint = did_you_mean(name_or_path, [n for n, _, _ in list_scenes()])
        raise ConfigError(f"unknown scene {name_or_path!r}{hint}; shipped scenes: {names} (or give a .toml path)")
    return f


def load_scene(name_or_path: str, overrides: Iterable[str] = ()) -> Scene:
    """Load a shipped scene by name or a TOML file by path, apply --set overrides, validate."""
    f = resolve(name_or_path)
    try:
        with open(f, "rb") as fh:
            d = tomllib.load(fh)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{f}: invalid TOML: {e}") from None
    except RecursionError:
        raise ConfigError(f"{f}: invalid scene: nested too deeply for a TOML scene") from None
    except UnicodeDecodeError as e:
        raise ConfigError(f"{f}: not a text TOML file ({e.reason})") from None
    except OSError as e:
        raise ConfigError(f"{f}: cannot read it: {e.strerror or e}") from None
    try:
        return scene_from_dict(apply_overrides(d, overrides), str(f))
    except RecursionError:
        raise ConfigError(f"{f}: invalid scene: nested too deeply") from None
