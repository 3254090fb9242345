"""Robot descriptions as users hold them: a URDF, a xacro, and a UR kinematics YAML on top.

A ``.xacro`` is processed with the ``xacro`` package from PyPI (no ROS install): ``--xacro-arg
NAME:=VALUE`` sets its ``<xacro:arg>`` values, and ``$(find PKG)`` resolves, in this order, to a
folder given as ``--package-path PKG=DIR``, then to a package found on ``ROS_PACKAGE_PATH`` (a
folder named PKG, or holding a ``package.xml`` that names PKG, up to three levels below each
entry), then to ``share/PKG`` of an ``AMENT_PREFIX_PATH`` prefix. The URDF text a xacro gives is
checked like any URDF (:func:`read_urdf_text`). A UR kinematics YAML, if given, is
applied on top of the result (:mod:`pincal.robot.ur_frames`).
"""

from __future__ import annotations

import contextlib
import os
import re
import threading
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from pincal.errors import RobotError
from pincal.inputs import note_input, read_bytes
from pincal.robot.ur_frames import URKinematics, apply_ur_kinematics, read_ur_kinematics
from pincal.robot.urdf_checks import declares_dtd, without_default_namespace
from pincal.sandbox import run_limited

#: Suffixes of the robot files ``load_robot`` reads (a ``.urdf.xacro`` ends in ``.xacro``).
URDF_SUFFIXES = (".urdf", ".xacro")
_XACRO_LOCK = threading.Lock()  # xacro keeps its state in module globals
#: Time [s] and memory [B] a xacro's processing may take (its expressions are Python).
XACRO_SECONDS = 30.0
XACRO_MEMORY = 2_000_000_000
_SEARCH_DEPTH = 3  # [folders] below each ROS_PACKAGE_PATH entry
#: What may come before a robot file's ``<?xml`` and is dropped: white space and a byte-order mark.
_LEADING = "\ufeff \t\r\n\f\v"


class PackageNotFoundError(RobotError):
    """A xacro's ``$(find PKG)`` names a package no ``--package-path`` or search path holds.

    Attributes:
        package: the package's name.
    """

    def __init__(self, package: str, where: str = "the xacro") -> None:
        super().__init__(
            f"{where} needs ROS package {package!r} ($(find {package})), which is not found: give "
            f"package_paths={package}=DIR (the folder holding its package.xml), or set ROS_PACKAGE_PATH"
        )
        self.package, self.where = package, where

    def __reduce__(self) -> tuple[type[PackageNotFoundError], tuple[str, str]]:
        return type(self), (self.package, self.where)  # sent back by a child process


def is_xacro(path: str | Path) -> bool:
    """True for a ``.xacro`` file (``robot.urdf.xacro`` included)."""
    return Path(path).suffix.lower() == ".xacro"


def check_urdf_text(text: str, path: Path) -> str:
    """``text`` (from ``path``) from its first markup on, refused if it has a DOCTYPE with declarations
    (which could make an XML parser read other files or expand entities without bound).

    Blank lines, spaces and a byte-order mark before ``<?xml`` are dropped: xacro output saved by
    common tools starts so, and urdfdom reads it, but an XML parser refuses a declaration that is
    not the first thing in the text.
    """
    text = text.lstrip(_LEADING)
    if "<!DOCTYPE" in text.upper() and declares_dtd(text):
        raise RobotError(
            f"URDF {path} has a DOCTYPE that declares entities or an external DTD, which could "
            "read other files: remove the <!DOCTYPE ...> block (a URDF needs none)"
        )
    return text


def parse_xacro_args(items: list[str] | tuple[str, ...] | None) -> dict[str, str]:
    """``NAME:=VALUE`` strings (as ``xacro`` takes them) as a mapping.

    Raises:
        RobotError: an item without ``:=`` or with an empty name.
    """
    out: dict[str, str] = {}
    for item in items or ():
        name, sep, value = item.partition(":=")
        if not sep or not name.strip():
            raise RobotError(f"xacro_args={item!r}: expected NAME:=VALUE (for example ur_type:=ur5e)")
        out[name.strip()] = value
    return out


def parse_package_paths(items: list[str] | tuple[str, ...] | None) -> dict[str, Path]:
    """``PKG=DIR`` strings as a mapping, each DIR an existing folder.

    Raises:
        RobotError: an item without ``=``, or a DIR that is not a folder.
    """
    out: dict[str, Path] = {}
    for item in items or ():
        name, sep, folder = item.partition("=")
        if not sep or not name.strip() or not folder.strip():
            raise RobotError(f"package_paths={item!r}: expected PKG=DIR (for example ur_description=src/ur)")
        path = Path(folder.strip()).expanduser()
        if not path.is_dir():
            raise RobotError(f"package_paths={item!r}: {path} is not a folder")
        out[name.strip()] = path.resolve()
    return out


def find_package(name: str, package_paths: Mapping[str, Path] | None = None) -> Path:
    """The folder of ROS package ``name`` (see the module's docstring for the search order).

    Raises:
        PackageNotFoundError: no folder found; the message names the package and what to give.
    """
    given = (package_paths or {}).get(name)
    if given is not None:
        return Path(given).resolve()  # xacro takes a relative path as relative to the includer
    for entry in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep):
        found = _search(Path(entry).resolve(), name, _SEARCH_DEPTH) if entry else None
        if found is not None:
            return found
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix and (Path(prefix) / "share" / name).is_dir():
            return (Path(prefix) / "share" / name).resolve()
    raise PackageNotFoundError(name)


def _search(folder: Path, name: str, depth: int) -> Path | None:
    """``folder`` or a folder below it (to ``depth`` levels) that is package ``name``."""
    if not folder.is_dir():
        return None
    if folder.name == name or _package_name(folder) == name:
        return folder
    if (folder / name).is_dir():
        return folder / name
    if depth == 0 or (folder / "package.xml").is_file():  # a package holds no other package
        return None
    with contextlib.suppress(OSError):
        for sub in sorted(folder.iterdir()):
            if sub.is_dir() and not sub.name.startswith("."):
                found = _search(sub, name, depth - 1)
                if found is not None:
                    return found
    return None


def _package_name(folder: Path) -> str | None:
    """The ``<name>`` of ``folder/package.xml``, or None."""
    manifest = folder / "package.xml"
    if not manifest.is_file():
        return None
    from lxml import etree

    try:
        root = etree.parse(str(manifest), etree.XMLParser(resolve_entities=False, no_network=True)).getroot()
    except (OSError, etree.XMLSyntaxError):
        return None
    found = root.findtext("name")
    return found.strip() if found else None


@contextlib.contextmanager
def _resolving(package_paths: Mapping[str, Path] | None) -> Iterator[None]:
    """xacro's ``$(find)`` and ``find()`` answered by :func:`find_package` (ROS's ament index
    is not needed), for the time of one processing."""
    from xacro import substitution_args

    def find(name: str) -> str:
        return str(find_package(name, package_paths))

    saved = substitution_args._eval_find, substitution_args._eval_dict.get("find")
    substitution_args._eval_find = find
    substitution_args._eval_dict["find"] = find
    try:
        yield
    finally:
        substitution_args._eval_find = saved[0]
        substitution_args._eval_dict["find"] = saved[1]


def _cause(exc: BaseException) -> BaseException | None:
    """A :class:`RobotError` xacro wrapped (in its ``exc`` attribute or as a cause), or None."""
    seen: set[int] = set()
    todo: list[BaseException | None] = [exc]
    while todo:
        item = todo.pop()
        if item is None or id(item) in seen:
            continue
        if isinstance(item, RobotError):
            return item
        seen.add(id(item))
        wrapped = getattr(item, "exc", None)
        todo += [wrapped if isinstance(wrapped, BaseException) else None, item.__cause__, item.__context__]
    return None


def xacro_to_urdf(
    path: str | Path,
    xacro_args: Mapping[str, str] | None = None,
    package_paths: Mapping[str, Path] | None = None,
) -> str:
    """The URDF text a xacro file gives, as ``xacro FILE NAME:=VALUE ...`` would print it.

    xacro evaluates the file's ``${...}`` expressions as Python: a hostile file can compute for
    ever (``${9**9**9}``) or fill the memory, so the processing runs within :data:`XACRO_SECONDS`
    and :data:`XACRO_MEMORY` (:func:`pincal.sandbox.run_limited`).

    Args:
        path: the ``.xacro`` file.
        xacro_args: values of its ``<xacro:arg>`` (NAME -> VALUE, as on xacro's command line).
        package_paths: package name -> folder, for ``$(find PKG)``.

    Raises:
        PackageNotFoundError: a ``$(find PKG)`` no folder answers.
        RobotError: the xacro package is missing, xacro refused the file, or it went past the
            time or memory limit.
    """
    try:
        import xacro  # noqa: F401
    except ImportError:
        raise RobotError(f"{path} is a xacro: install the xacro package (pip install xacro)") from None
    path = Path(path).resolve()
    with _XACRO_LOCK:
        text, includes = run_limited(
            _process,
            (path, dict(xacro_args or {}), package_paths),
            seconds=XACRO_SECONDS,
            memory=XACRO_MEMORY,
            what=f"cannot process xacro {path}",
        )
    for include in [str(path), *map(str, includes)]:  # outputs must not replace them (issue 33)
        note_input(include, f"file {Path(include).name} the xacro includes")
    declared = _declared_args([path, *(Path(f) for f in includes)])
    unknown = sorted(set(xacro_args or {}) - declared)
    if unknown:
        have = ", ".join(sorted(declared)) or "none"
        raise RobotError(f"xacro_args={unknown[0]}: {path.name} declares no such argument (it has: {have})")
    return text


def _process(
    path: Path, xacro_args: dict[str, str], package_paths: Mapping[str, Path] | None
) -> tuple[str, list[str]]:
    """xacro's processing of ``path``: the URDF text and the files it included."""
    import xacro

    with _resolving(package_paths), _from_first_markup(xacro):
        xacro.all_includes = []
        try:
            doc = xacro.process_file(str(path), mappings=xacro_args, verbosity=0)
        except Exception as exc:  # xacro raises many kinds of error for a broken file
            cause = _cause(exc)
            if isinstance(cause, PackageNotFoundError):
                raise PackageNotFoundError(cause.package, path.name) from None
            if cause is not None:
                raise cause from None
            raise RobotError(f"cannot process xacro {path}: {' '.join(str(exc).split())}") from None
        finally:
            xacro.init_stacks(None)
        return str(doc.toprettyxml(indent="  ")), list(xacro.all_includes)


@contextlib.contextmanager
def _from_first_markup(xacro: Any) -> Iterator[None]:
    """xacro reading each file (the xacro and those it includes) from its first markup on, as
    :func:`check_urdf_text` reads a URDF: a blank line before ``<?xml`` is no error."""
    parse = xacro.parse

    def lenient(inp: Any, filename: str | None = None) -> Any:
        if inp is None and filename is not None:
            with contextlib.suppress(OSError, UnicodeDecodeError):
                text = Path(os.path.join(xacro.root_dir, filename)).read_text(encoding="utf-8")
                inp = text.lstrip(_LEADING)
        return parse(inp, filename)

    xacro.parse = lenient
    try:
        yield
    finally:
        xacro.parse = parse


_ARG = re.compile(r"<\s*[\w.-]+:arg\b[^>]*?\bname\s*=\s*[\"']([^\"']+)[\"']")


def _declared_args(files: list[Path]) -> set[str]:
    """Names of the ``<xacro:arg>`` the files declare."""
    names: set[str] = set()
    for file in files:
        with contextlib.suppress(OSError, UnicodeDecodeError):
            names.update(_ARG.findall(file.read_text(encoding="utf-8")))
    return names


MAX_URDF_BYTES = 50_000_000  # [bytes] far above any robot description


def read_urdf_text(path: Path) -> str:
    """The text of a URDF, refused if it declares entities or an external DTD.

    Kinematic calibration reads only the URDF itself: meshes (``package://`` or relative paths)
    are never opened, and a DOCTYPE that could make an XML parser read a local file, the
    network, or expand entities (``<!ENTITY``, ``SYSTEM``, ``PUBLIC``) is refused before any
    parser sees the text.

    Raises:
        RobotError: unreadable file, not UTF-8, too large, or a DOCTYPE with declarations.
    """
    try:
        text = read_bytes(path, "URDF", MAX_URDF_BYTES, error=RobotError).decode("utf-8")  # bounded
    except UnicodeDecodeError as exc:
        raise RobotError(f"cannot read URDF {path}: {exc}") from None
    return check_urdf_text(text, path)


def robot_description(
    path: Path,
    xacro_args: Mapping[str, str] | None = None,
    package_paths: Mapping[str, Path] | None = None,
    kinematics: str | Path | URKinematics | None = None,
) -> str:
    """The URDF text of a robot file: a URDF as written, or a xacro processed; then, if
    ``kinematics`` is given, a UR kinematics YAML applied on top
    (:func:`pincal.robot.ur_frames.apply_ur_kinematics`).

    Raises:
        RobotError: the file cannot be read or processed, or options that need a xacro without one.
    """
    if is_xacro(path):
        read_urdf_text(path)  # the same checks on the xacro's own text
        text = check_urdf_text(xacro_to_urdf(path, xacro_args, package_paths), path)
    elif xacro_args:
        raise RobotError(f"xacro_args= is for a .xacro robot file, and {path.name} is not one")
    else:
        text = read_urdf_text(path)
    text = without_default_namespace(text)  # issue 33: the writers look elements up by plain name
    if kinematics is not None:
        given = kinematics if isinstance(kinematics, URKinematics) else read_ur_kinematics(kinematics)
        text = apply_ur_kinematics(text, given)
    return text
