"""Machine, tool and cutting-data profiles in TOML.

Looked up, later sources winning: the examples shipped with ncopt, the user's
config folder (``platformdirs.user_config_dir("ncopt")/ncopt.toml``), a
project-local ``ncopt.toml`` in the working folder, then a file given with
``--tools``.  Command-line options win over every profile.

A file may hold::

    default_machine = "tajmac"
    [machines.tajmac]      # accel_rad_s2, max_rpm, min_rpm, max_feed_mm_min,
    accel_rad_s2 = 227     # rapid_mm_min, control, min_s_interval_ms, decimal_point,
                           # s_changes, kinematics (5-axis: xyzac-trt, ..., see
                           # ncopt.kinematics)
    max_rpm = 15000
    [tools.4]              # by T number or by name: type (ball | bull-nose),
    type = "ball"          # diameter_mm, corner_radius_mm, teeth
    diameter_mm = 16
    teeth = 2
    [cutting."1.4462"]     # vc_m_min, fz_mm
    vc_m_min = 70
    fz_mm = 0.1
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from .errors import FileError, UsageError
from .model import Cutter, CuttingData

EXAMPLES = Path(__file__).resolve().parent / "data" / "examples.toml"
PROJECT_FILE = "ncopt.toml"


@dataclass(frozen=True)
class MachineProfile:
    name: str
    source: str
    accel_rad_s2: float
    max_rpm: float
    min_rpm: float = 0.0
    max_feed_mm_min: float = float("inf")
    rapid_mm_min: float = 10000.0
    control: str | None = None
    min_s_interval_ms: float = 0.0
    decimal_point: str | None = None  # Fanuc: calculator, is-b or is-c
    s_changes: str | None = None  # anywhere or between-passes (None: the control's default)
    kinematics: str | None = None  # 5-axis: a name of ncopt.kinematics.NAMES


@dataclass(frozen=True)
class Profiles:
    """Everything found, with where each entry came from."""

    machines: dict = field(default_factory=dict)
    tools: dict = field(default_factory=dict)  # key (int T or str name) -> (Cutter, source)
    cutting: dict = field(default_factory=dict)  # name -> (CuttingData, source)
    default_machine: tuple | None = None  # (name, source)
    sources: tuple = ()

    def machine(self, name: str) -> MachineProfile:
        if name not in self.machines:
            known = ", ".join(sorted(self.machines)) or "none"
            raise UsageError(f"no machine profile {name!r} (known: {known}); see ncopt profiles")
        return self.machines[name]

    def tool(self, key: int | str) -> Cutter | None:
        entry = self.tools.get(key)
        return entry[0] if entry else None

    def material(self, name: str) -> CuttingData:
        if name not in self.cutting:
            known = ", ".join(sorted(self.cutting)) or "none"
            raise UsageError(f"no cutting data for {name!r} (known: {known}); see ncopt profiles")
        return self.cutting[name][0]


def user_file() -> Path:
    from platformdirs import user_config_dir
    return Path(user_config_dir("ncopt")) / "ncopt.toml"


def search_paths(cwd: Path | None = None, tools_file: Path | None = None) -> list[Path]:
    """Profile files in the order they apply (later ones win)."""
    try:
        here = cwd or Path.cwd()
    except OSError as exc:
        raise FileError(f"cannot read the working folder: {exc.strerror}; change into a "
                        "folder that exists", ".") from None
    paths = [EXAMPLES, user_file(), here / PROJECT_FILE]
    if tools_file is not None:
        if not _is_file(Path(tools_file)):
            raise UsageError("the tools file does not exist; check --tools", str(tools_file))
        paths.append(Path(tools_file))
    return [p for p in paths if _is_file(p)]


def _is_file(path: Path) -> bool:
    """Whether a profile file is there; a folder that cannot be searched is an error (a
    HOME of another user, as under sudo without -H), not a file that is missing."""
    try:
        return path.is_file()
    except OSError as exc:
        raise FileError(f"cannot read the profile: {exc.strerror}; {_UNREADABLE}",
                        str(path)) from None


_UNREADABLE = ("check the folder's permissions, or point HOME (or XDG_CONFIG_HOME) at a "
               "folder of this user (sudo -H)")


def load(cwd: Path | None = None, tools_file: Path | None = None) -> Profiles:
    """Read every profile file that applies."""
    machines, tools, cutting, default = {}, {}, {}, None
    files = search_paths(cwd, tools_file)
    for path in files:
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except OSError as exc:
            raise FileError(f"cannot read the profile: {exc.strerror}; {_UNREADABLE}",
                            str(path)) from None
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise UsageError(f"cannot read the profile: {exc}; fix the TOML", str(path)) from None
        src = str(path)
        try:
            for name, m in data.get("machines", {}).items():
                machines[name] = _machine(name, m, src)
            for key, t in data.get("tools", {}).items():
                tools[int(key) if str(key).isdigit() else key] = (_tool(key, t, src), src)
            for name, c in data.get("cutting", {}).items():
                cutting[name] = (_cutting(name, c, src), src)
        except (ValueError, TypeError, AttributeError) as exc:
            raise UsageError(f"a value of the wrong kind ({exc}); numbers must be numbers "
                             "and sections tables", src) from None
        if "default_machine" in data:
            default = (data["default_machine"], src)
    return Profiles(machines, tools, cutting, default, tuple(str(p) for p in files))


def _need(entry: dict, key: str, what: str, src: str):
    if key not in entry:
        raise UsageError(f"{what} has no {key}; add it", src)
    return entry[key]


def _number(entry: dict, key: str, what: str, src: str, default=None) -> float:
    """A number from a profile entry, or a message naming the key."""
    value = _need(entry, key, what, src) if default is None else entry.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise UsageError(f"{what}: {key} must be a number, not {value!r}", src)
    return float(value)


def _machine(name: str, m: dict, src: str) -> MachineProfile:
    what = f"machine {name!r}"
    if not isinstance(m, dict):
        raise UsageError(f"{what} must be a table [machines.{name}]", src)
    return MachineProfile(name, src, _number(m, "accel_rad_s2", what, src),
                          _number(m, "max_rpm", what, src), _number(m, "min_rpm", what, src, 0.0),
                          _number(m, "max_feed_mm_min", what, src, float("inf")),
                          _number(m, "rapid_mm_min", what, src, 10000.0), m.get("control"),
                          _number(m, "min_s_interval_ms", what, src, 0.0), m.get("decimal_point"),
                          m.get("s_changes"), _kinematics(m, what, src))


def _kinematics(m: dict, what: str, src: str) -> str | None:
    from .kinematics import NAMES

    name = m.get("kinematics")
    if name is not None and name not in NAMES:
        raise UsageError(f"{what}: kinematics must be one of {', '.join(NAMES)}, not {name!r}",
                         src)
    return name


def _tool(key, t: dict, src: str) -> Cutter:
    what = f"tool {key!r}"
    if not isinstance(t, dict):
        raise UsageError(f"{what} must be a table [tools.{key}]", src)
    d = _number(t, "diameter_mm", what, src)
    kind = t.get("type", "ball")
    if kind not in ("ball", "bull-nose"):
        raise UsageError(f"{what}: type must be ball or bull-nose, not {kind!r}", src)
    r = d / 2 if kind == "ball" else _number(t, "corner_radius_mm", what, src)
    return Cutter(d, int(_number(t, "teeth", what, src, 2)), r)


def _cutting(name: str, c: dict, src: str) -> CuttingData:
    what = f"cutting data {name!r}"
    if not isinstance(c, dict):
        raise UsageError(f"{what} must be a table [cutting.{name}]", src)
    return CuttingData(_number(c, "vc_m_min", what, src), _number(c, "fz_mm", what, src))


def render_profiles(found: Profiles, console) -> None:
    """What ``ncopt profiles`` prints: the files read and a table per kind of profile."""
    from rich.table import Table

    say = lambda text: console.print(text, markup=False)  # noqa: E731
    say(f"profile files, later ones win (user file: {user_file()}; project file: "
        f"./{PROJECT_FILE}):")
    for src in found.sources:
        say(f"  {src}")
    t = Table(title="machines")
    for col in ("name", "accel rad/s^2", "max RPM", "control", "from"):
        t.add_column(col)
    for m in found.machines.values():
        t.add_row(m.name, f"{m.accel_rad_s2:g}", f"{m.max_rpm:g}", m.control or "detected",
                  m.source)
    console.print(t)
    t = Table(title="tools")
    for col in ("T / name", "cutter", "from"):
        t.add_column(col)
    for key, (c, src) in found.tools.items():
        kind = "ball" if c.is_ball else f"bull-nose r{c.corner_radius_mm:g}"
        t.add_row(str(key), f"D{c.diameter_mm:g} {kind}, {c.teeth} teeth", src)
    console.print(t)
    t = Table(title="cutting data")
    for col in ("material", "vc m/min", "fz mm", "from"):
        t.add_column(col)
    for name, (c, src) in found.cutting.items():
        t.add_row(name, f"{c.vc_m_min:g}", f"{c.fz_mm:g}", src)
    console.print(t)
    if found.default_machine:
        say(f"default machine: {found.default_machine[0]} ({found.default_machine[1]})")
