"""Machine, tool and cutting-data profiles in TOML.

Looked up, later sources winning: the examples shipped with ncopt, the user's
config folder (``platformdirs.user_config_dir("ncopt")/ncopt.toml``), the
project's ``ncopt.toml`` (the nearest one from the working folder up, as black
finds its pyproject.toml: the search stops at a folder holding ``.git`` or at the
root), then a file given with ``--tools``.  Command-line options win over every
profile; ``NCOPT_MACHINE`` names the default machine over ``default_machine``.
A key ncopt does not know (a misspelling) is refused with the file and its line, and so
is a value outside the range its key allows (``accel_rad_s2 = nan``, ``teeth = 2.5``,
``max_rpm = inf``, a ``min_rpm`` not below ``max_rpm``): the ranges of
:data:`ncopt.model.LIMITS`, which the command line's options share.

A file may hold::

    default_machine = "tajmac"
    [machines.tajmac]      # accel_rad_s2, max_rpm, min_rpm, max_feed_mm_min,
    accel_rad_s2 = 227     # rapid_mm_min, control, min_s_interval_ms, decimal_point,
                           # s_changes, kinematics (5-axis: xyzac-trt, ..., see
                           # ncopt.motion.kinematics)
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

import difflib
import os
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from ncopt.runtime.errors import FileError, UsageError
from ncopt.model import LIMITS, Cutter, CuttingData, min_below_max

EXAMPLES = Path(__file__).resolve().parent.parent / "data" / "examples.toml"
PROJECT_FILE = "ncopt.toml"
MACHINE_ENV = "NCOPT_MACHINE"  # names the default machine profile (--machine wins)

# Every key a profile may hold, with what it means and its unit: the keys checked on
# reading (a misspelt one is refused) and the comments of ``ncopt profiles init``.
MACHINE_KEYS = {
    "accel_rad_s2": "Spindle acceleration, rad/s^2 (required): how fast the spindle changes "
                    "speed, as its maker states it or as measured (0 to max_rpm in t s: "
                    "max_rpm * 2 pi / 60 / t).",
    "max_rpm": "Highest spindle speed, RPM (required).",
    "min_rpm": "Lowest spindle speed, RPM (default 0).",
    "max_feed_mm_min": "Highest feed the control runs, mm/min (default: no limit; inf).",
    "rapid_mm_min": "Rapid traverse rate, mm/min, for the time estimates (default 10000).",
    "control": "The control: {controls} (default: detected from each program).",
    "min_s_interval_ms": "Least time between two S words, ms (default 0; a Sinumerik PLC "
                         "may need 100).",
    "decimal_point": "Fanuc only: how X25 without a decimal point is read: {conventions} "
                     "(default: none; a program that needs it is refused).",
    "s_changes": "Where S may change: {s_changes} (default: between-passes for grbl, else "
                 "anywhere).",
    "kinematics": "5-axis: how the rotary axes tilt the tool: {kinematics} (default: none, "
                  "3-axis; programs of tool vectors need none).",
    "tcp": "5-axis: always where the control runs tool-tip kinematics (TCP) for every program "
           "(default: only where the program switches it on: G43.4/G43.5, TRAORI, M128, M428).",
    "note": "Free text for people; ncopt does not read it.",
}
TOOL_KEYS = ("type", "diameter_mm", "corner_radius_mm", "teeth", "note")
CUTTING_KEYS = ("vc_m_min", "fz_mm", "note")
TOP_KEYS = ("default_machine", "machines", "tools", "cutting")


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
    kinematics: str | None = None  # 5-axis: a name of ncopt.motion.kinematics.NAMES
    tcp: str | None = None  # "always": the control runs tool-tip kinematics for every program


@dataclass(frozen=True)
class Profiles:
    """Everything found, with where each entry came from."""

    machines: dict = field(default_factory=dict)
    tools: dict = field(default_factory=dict)  # key (int T or str name) -> (Cutter, source)
    cutting: dict = field(default_factory=dict)  # name -> (CuttingData, source)
    default_machine: tuple[str, str] | None = None  # (name, source)
    sources: tuple[str, ...] = ()  # the files read, in order

    def machine(self, name: str) -> MachineProfile:
        if name not in self.machines:
            known = ", ".join(sorted(self.machines)) or "none"
            raise UsageError(f"no machine profile {name!r} (known: {known}); see ncopt profiles")
        return self.machines[name]

    def chosen_machine(self, name: str | None) -> MachineProfile | None:
        """The profile of ``--machine NAME``, else the default machine (NCOPT_MACHINE,
        else the files' default_machine); None where none is named."""
        if name is not None:
            return self.machine(name)
        if self.default_machine is None:
            return None
        default, source = self.default_machine
        if default not in self.machines:
            known = ", ".join(sorted(self.machines)) or "none"
            raise UsageError(f"no machine profile {default!r}, which {_named_by(source)} as "
                             f"the default machine (known: {known}); see ncopt profiles")
        return self.machines[default]

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


def _named_by(source: str) -> str:
    return f"the {MACHINE_ENV} environment variable names" if source == MACHINE_ENV \
        else f"default_machine in {source} names"


def search_paths(cwd: Path | None = None, tools_file: Path | None = None) -> list[Path]:
    """Profile files in the order they apply (later ones win)."""
    try:
        here = cwd or Path.cwd()
    except OSError as exc:
        raise FileError(f"cannot read the working folder: {exc.strerror}; change into a "
                        "folder that exists", ".") from None
    paths = [EXAMPLES, user_file()]
    project = project_file(here)
    if project is not None and project not in paths:
        paths.append(project)
    if tools_file is not None:
        if not _is_file(Path(tools_file)):
            raise UsageError("the tools file does not exist; check --tools", str(tools_file))
        paths.append(Path(tools_file))
    return [p for p in paths if _is_file(p)]


def project_file(start: Path) -> Path | None:
    """The nearest ``ncopt.toml`` in ``start`` or a folder above it; the search stops at
    a folder holding ``.git`` (the project's root) or at the filesystem's root."""
    for folder in (start, *start.parents):
        candidate = folder / PROJECT_FILE
        if _is_file(candidate):
            return candidate
        if _exists(folder / ".git"):
            return None
    return None


def _exists(path: Path) -> bool:
    try:
        return path.exists()
    except OSError:
        return False


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
        text, data = _read(path)
        src = str(path)
        check_keys(data, src, text)
        try:
            for name, m in data.get("machines", {}).items():
                machines[name] = _machine(name, m, src, text)
            for key, t in data.get("tools", {}).items():
                tools[int(key) if str(key).isdigit() else key] = (_tool(key, t, src, text), src)
            for name, c in data.get("cutting", {}).items():
                cutting[name] = (_cutting(name, c, src, text), src)
        except UsageError:
            raise
        except (ValueError, TypeError, AttributeError) as exc:
            raise UsageError(f"a value of the wrong kind ({exc}); numbers must be numbers "
                             "and sections tables", src) from None
        if "default_machine" in data:
            if not isinstance(data["default_machine"], str):
                raise UsageError("default_machine must be a machine's name in quotes", src)
            default = (data["default_machine"], src)
    env = os.environ.get(MACHINE_ENV, "").strip()
    if env:
        default = (env, MACHINE_ENV)
    return Profiles(machines, tools, cutting, default, tuple(str(p) for p in files))


def _read(path: Path) -> tuple[str, dict]:
    """A profile file's text and its TOML; UsageError or FileError naming the file."""
    try:
        text = path.read_text(encoding="utf-8")
        return text, tomllib.loads(text)
    except OSError as exc:
        raise FileError(f"cannot read the profile: {exc.strerror}; {_UNREADABLE}",
                        str(path)) from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise UsageError(f"cannot read the profile: {exc}; fix the TOML", str(path)) from None
    except RecursionError:  # arrays or inline tables nested hundreds deep
        raise UsageError("cannot read the profile: its arrays or tables are nested too deep "
                         "to read (hundreds of levels); a profile needs two: fix the TOML",
                         str(path)) from None


def check_keys(data: dict, src: str, text: str = "") -> None:
    """Refuse a key ncopt does not know (UsageError naming the file, the line where
    ``text`` shows it, and the nearest known key): a misspelt key would otherwise be
    dropped without a word and its default used."""
    _check_table(data, TOP_KEYS, "", src, text, "")
    for section, known, what in (("machines", tuple(MACHINE_KEYS), "machine"),
                                 ("tools", TOOL_KEYS, "tool"), ("cutting", CUTTING_KEYS,
                                                                "cutting data")):
        entries = data.get(section, {})
        if not isinstance(entries, dict):
            raise UsageError(f"{section} must be a table [{section}.NAME]", src)
        for name, entry in entries.items():
            if isinstance(entry, dict):
                _check_table(entry, known, f"{what} {name!r}", src, text, name)


def _check_table(entry: dict, known, what: str, src: str, text: str, name: str) -> None:
    for key in entry:
        if key in known:
            continue
        close = [k for k in known if k.startswith(f"{key}_")]  # the unit left out: fz
        close = close or difflib.get_close_matches(key, known, n=1, cutoff=0.6)
        hint = f"did you mean {close[0]}?" if close else f"the keys are {', '.join(known)}"
        where = f" in {what}" if what else ""
        raise UsageError(f"unknown key {key}{where}; {hint}", src, _key_line(text, name, key))


def _key_line(text: str, table: str, key: str) -> int | None:
    """1-based line where ``key =`` is written (after the header of ``table`` when it has
    one), or None where the text does not show it plainly."""
    lines = text.splitlines()
    start = 0
    if table:
        header = re.compile(r"^\s*\[\s*\w+\s*\.\s*[\"']?" + re.escape(table) + r"[\"']?\s*\]")
        start = next((i for i, ln in enumerate(lines) if header.match(ln)), 0)
    assign = re.compile(r"^\s*[\"']?" + re.escape(key) + r"[\"']?\s*=")
    return next((i + 1 for i in range(start, len(lines)) if assign.match(lines[i])), None)


def _need(entry: dict, key: str, what: str, src: str):
    if key not in entry:
        raise UsageError(f"{what} has no {key}; add it", src)
    return entry[key]


def _number(entry: dict, key: str, what: str, src: str, default=None, text: str = "",
            table: str = ""):
    """A number from a profile entry within the bounds ncopt allows for ``key``
    (:data:`ncopt.model.LIMITS`), or a message naming the key, the file and its line."""
    value = _need(entry, key, what, src) if default is None else entry.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise UsageError(f"{what}: {key} must be a number, not {value!r}", src)
    bounds = LIMITS.get(key)
    if bounds is not None and not bounds.holds(value):
        raise UsageError(f"{what}: {key} must be {bounds.describe()}, not {value!r}", src,
                         _key_line(text, table, key))
    return value if bounds is not None and bounds.integer else float(value)


def _machine(name: str, m: dict, src: str, text: str = "") -> MachineProfile:
    what = f"machine {name!r}"
    if not isinstance(m, dict):
        raise UsageError(f"{what} must be a table [machines.{name}]", src)
    num = lambda key, default=None: _number(m, key, what, src, default, text, name)  # noqa: E731
    accel, max_rpm, min_rpm = num("accel_rad_s2"), num("max_rpm"), num("min_rpm", 0.0)
    why = min_below_max(min_rpm, max_rpm)
    if why:
        raise UsageError(f"{what}: min_rpm: {why}", src, _key_line(text, name, "min_rpm")
                         or _key_line(text, name, "max_rpm"))
    return MachineProfile(name, src, accel, max_rpm, min_rpm,
                          num("max_feed_mm_min", float("inf")), num("rapid_mm_min", 10000.0),
                          _one_of(m, "control", what, src),
                          num("min_s_interval_ms", 0.0),
                          _one_of(m, "decimal_point", what, src),
                          _one_of(m, "s_changes", what, src),
                          _kinematics(m, what, src), _one_of(m, "tcp", what, src))


def _choices() -> dict:
    """The values each named setting of a machine takes."""
    from ncopt.reading.controls import CONTROLS, S_CHANGES
    from ncopt.reading.dialect import DECIMAL_POINT_CONVENTIONS
    from ncopt.motion.kinematics import NAMES

    return {"control": tuple(CONTROLS), "decimal_point": DECIMAL_POINT_CONVENTIONS,
            "s_changes": S_CHANGES, "kinematics": NAMES, "tcp": ("always",)}


def _one_of(m: dict, key: str, what: str, src: str) -> str | None:
    """A named setting, refused with the nearest valid value when it is none of them."""
    value, choices = m.get(key), _choices()[key]
    if value is None or value in choices:
        return value
    close = difflib.get_close_matches(str(value), choices, n=1, cutoff=0.6)
    hint = f"; did you mean {close[0]}?" if close else ""
    raise UsageError(f"{what}: {key} must be one of {', '.join(choices)}, not {value!r}{hint}",
                     src)


def _kinematics(m: dict, what: str, src: str) -> str | None:
    from ncopt.motion.kinematics import NAMES

    name = m.get("kinematics")
    if name is not None and name not in NAMES:
        raise UsageError(f"{what}: kinematics must be one of {', '.join(NAMES)}, not {name!r}",
                         src)
    return name


def _tool(key, t: dict, src: str, text: str = "") -> Cutter:
    what = f"tool {key!r}"
    if not isinstance(t, dict):
        raise UsageError(f"{what} must be a table [tools.{key}]", src)
    d = _number(t, "diameter_mm", what, src, text=text, table=str(key))
    kind = t.get("type", "ball")
    if kind not in ("ball", "bull-nose"):
        raise UsageError(f"{what}: type must be ball or bull-nose, not {kind!r}", src,
                         _key_line(text, str(key), "type"))
    r = d / 2 if kind == "ball" else _number(t, "corner_radius_mm", what, src, text=text,
                                             table=str(key))
    if r > d / 2 * (1 + 1e-9):
        raise UsageError(f"{what}: corner_radius_mm must be at most half of diameter_mm "
                         f"({d / 2:g} mm), not {r!r}", src,
                         _key_line(text, str(key), "corner_radius_mm"))
    return Cutter(d, _number(t, "teeth", what, src, 2, text, str(key)), r)


def _cutting(name: str, c: dict, src: str, text: str = "") -> CuttingData:
    what = f"cutting data {name!r}"
    if not isinstance(c, dict):
        raise UsageError(f"{what} must be a table [cutting.{name}]", src)
    return CuttingData(_number(c, "vc_m_min", what, src, text=text, table=name),
                       _number(c, "fz_mm", what, src, text=text, table=name))


def render_profiles(found: Profiles, console) -> None:
    """What ``ncopt profiles`` prints: the files read and a table per kind of profile."""
    from ncopt.runtime.stdio import count

    say = lambda text: console.print(text, markup=False)  # noqa: E731
    say(f"profile files, later ones win (user file: {user_file()}; project file: the "
        f"nearest {PROJECT_FILE} from here up):")
    for src in found.sources:
        say(f"  {src}")
    _table(console, "machines", ("name", "accel rad/s^2", "max RPM", "control"),
           [(m.name, f"{m.accel_rad_s2:g}", f"{m.max_rpm:g}", m.control or "detected",
             m.source) for m in found.machines.values()])
    _table(console, "tools", ("T / name", "cutter"),
           [(str(key), f"D{c.diameter_mm:g} "
             f"{'ball' if c.is_ball else f'bull-nose r{c.corner_radius_mm:g}'}, "
             f"{count(c.teeth, 'tooth', 'teeth')}", src)
            for key, (c, src) in found.tools.items()])
    _table(console, "cutting data", ("material", "vc m/min", "fz mm"),
           [(name, f"{c.vc_m_min:g}", f"{c.fz_mm:g}", src)
            for name, (c, src) in found.cutting.items()])
    if found.default_machine:
        name, source = found.default_machine
        where = f"the {MACHINE_ENV} environment variable" if source == MACHINE_ENV else source
        say(f"default machine: {name} ({where})")


FROM_MIN = 24  # the file column folds its paths down to this width


def _table(console, title: str, heads: tuple, rows: list) -> None:
    """A table whose cells are never cut: each column as wide as its widest cell, the last
    one ("from", a path) folded over lines where the terminal is narrower; where even that
    does not fit, the table is wider than the terminal (which wraps it) rather than cut."""
    from rich.table import Table

    t = Table(title=title)
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h)
              for i, h in enumerate(heads)]
    for head, width in zip(heads, widths):
        t.add_column(head, no_wrap=True, min_width=width)
    t.add_column("from", overflow="fold")
    for row in rows:
        t.add_row(*row)
    needed = sum(widths) + FROM_MIN + 3 * (len(heads) + 1) + 1
    width = console.width
    console.width = max(width, needed)
    try:
        console.print(t)
    finally:
        console.width = width


# ------------------------------------------------------------ profiles init ----
_DEFAULTS = {f: MachineProfile.__dataclass_fields__[f].default
             for f in ("min_rpm", "max_feed_mm_min", "rapid_mm_min", "control",
                       "min_s_interval_ms", "decimal_point", "s_changes", "kinematics",
                       "tcp")}


def machine_template(name: str, base: MachineProfile | None = None) -> str:
    """A commented TOML file for machine ``name``: every key with what it means and its
    unit.  With ``base`` (a known profile) its values are filled in; otherwise the two
    required keys are left for the user to measure (ncopt never guesses a spindle), so
    the file is refused until they are given."""
    choices = {k: ", ".join(v) for k, v in _choices().items()}
    out = [f"# ncopt machine profile {name!r} (written by: ncopt profiles init {name}).",
           "# Profiles are read from, later ones winning: the examples shipped with ncopt,",
           f"# the user file ({user_file()}), the nearest {PROJECT_FILE}",
           "# from the working folder up (the search stops at a folder holding .git), then",
           "# --tools FILE.  Options on the command line win over every profile.  A key",
           "# ncopt does not know is refused with the file and the line.",
           "",
           "# The machine used when no --machine is given (the NCOPT_MACHINE environment",
           "# variable names another); remove the '#' to make it this one:",
           f"# default_machine = {_toml_string(name)}",
           "", f"[machines.{_toml_key(name)}]"]
    for key, meaning in MACHINE_KEYS.items():
        if key == "note":
            continue
        text = meaning.format(controls=choices["control"], conventions=choices["decimal_point"],
                              s_changes=choices["s_changes"], kinematics=choices["kinematics"])
        out += _wrapped(text)
        value = getattr(base, key) if base is not None else None
        if key in _DEFAULTS and value == _DEFAULTS[key]:
            value = None
        if value is not None:
            out.append(f"{key} = {_toml_value(value)}")
        elif key not in _DEFAULTS:
            out.append(f"# {key} =    # required: give your figure and remove the '#'")
        else:
            default = _DEFAULTS[key]
            out.append(f"# {key} =" + ("" if default is None else f" {_toml_value(default)}"))
    out += _wrapped(MACHINE_KEYS["note"]) + ['# note = ""']
    return "\n".join(out) + "\n"


def _wrapped(text: str, width: int = 88) -> list[str]:
    import textwrap
    return ["", *("# " + line for line in textwrap.wrap(text, width - 2, break_on_hyphens=False))]


def _toml_value(value) -> str:
    if isinstance(value, str):
        return _toml_string(value)
    if value == float("inf"):
        return "inf"
    return str(int(value)) if float(value).is_integer() else repr(float(value))


def _toml_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _toml_key(name: str) -> str:
    return name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else _toml_string(name)
