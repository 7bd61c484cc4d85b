"""MJCF (MuJoCo XML) files read as untrusted input, resolved before Pinocchio reads them.

Model files come from the internet, so this module reads them with
`defusedxml` (no entity expansion, no DTD, no external references: a "billion
laughs" file is refused at once with `UnsafeModelFileError`), reads only the
files the model names (``<include>`` files, resolved against the model's
folder; a path that leaves the folder is refused unless the caller allows it),
and caps the size of what it reads (`MAX_FILE_BYTES`, `MAX_INCLUDES`).

It then rewrites the tree so that Pinocchio's MJCF parser loses nothing it can
be told explicitly (`resolve`):

* ``<include>`` elements are replaced by the children of the included file's
  ``<mujoco>`` root (MuJoCo's rule);
* every ``joint``, ``geom`` and ``site`` of ``<worldbody>`` gets the attributes
  its default class (``class=``, else the nearest ``childclass``, else
  ``main``) would give it, written on the element itself (and so does each
  ``<general>`` actuator, whose class may give it activation dynamics). Pinocchio 4.1 ignores
  a joint ``pos`` and a geom ``mass``/``pos``/``quat`` that come from a class;
  written inline they are read. MuJoCo's own reading of the file is unchanged
  (an inline attribute equals the class's value).

Nothing here knows Pinocchio; `contactdiff.model.mjcf` builds the model.
"""

from __future__ import annotations

import copy
import re
from dataclasses import dataclass, field
from pathlib import Path
from xml.etree.ElementTree import Element

from ..errors import ModelLoadError, UnsafeModelFileError

MAX_FILE_BYTES = 20_000_000
"""bytes: the largest MJCF (or included) file read; Menagerie's largest XML is ~0.3 MB."""

MAX_INCLUDES = 200
"""The most ``<include>`` files one model may pull in (a cycle or a flood is refused)."""

BODY_TREE_TAGS = ("joint", "geom", "site")
"""Elements of ``<worldbody>`` whose default-class attributes are written inline."""

_ORIENTATION = ("quat", "axisangle", "euler", "xyaxes", "zaxis")
_FROMTO_REPLACES = ("pos",) + _ORIENTATION  # MuJoCo ignores these where fromto is given

_ASSET_FILE_TAGS = ("mesh", "texture", "hfield", "skin", "model")


@dataclass
class MJCFDocument:
    """An MJCF model with its includes resolved.

    Attributes:
        path: the main file.
        root: the ``<mujoco>`` element (includes replaced, classes not yet inlined).
        files: every file read, the main one first.
        classes: default classes, ``{class: {tag: {attribute: value}}}`` (inherited
            values included), ``main`` for the top level.
    """

    path: Path
    root: Element
    files: list[Path] = field(default_factory=list)
    classes: dict[str, dict[str, dict[str, str]]] = field(default_factory=dict)


MJCF_SUFFIXES = (".xml", ".mjcf")
"""File name endings of MJCF files (MuJoCo's own are ``.xml``)."""


def looks_like_mjcf(path: str | Path) -> bool:
    """Whether ``path`` is an existing file ending in one of `MJCF_SUFFIXES` whose root
    element is ``<mujoco>`` (its first 64 kB are looked at; nothing is parsed)."""
    path = Path(path)
    if path.suffix.lower() not in MJCF_SUFFIXES or not path.is_file():
        return False
    with open(path, "rb") as f:
        head = f.read(65536).decode("utf-8", errors="replace")
    head = re.sub(r"<!--.*?-->", "", head, flags=re.S)  # comments before the root
    head = re.sub(r"<\?.*?\?>", "", head, flags=re.S)  # the XML declaration
    match = re.search(r"<\s*([A-Za-z_][\w.-]*)", head)
    return match is not None and match.group(1) == "mujoco"


def parse_xml_file(path: Path, what: str = "MJCF") -> Element:
    """Parse one XML file with defusedxml.

    Raises:
        UnsafeModelFileError: the file declares entities or a DTD (entity
            expansion, external references) or is larger than `MAX_FILE_BYTES`.
        ModelLoadError: the file is missing or is not well-formed XML.
    """
    from defusedxml import DefusedXmlException
    from defusedxml.ElementTree import ParseError, fromstring

    if not path.is_file():
        raise ModelLoadError(
            f"{what} file {str(path)!r} does not exist"
            if not path.exists()
            else f"{what} path {str(path)!r} is not a regular file"
        )
    size = path.stat().st_size
    if size > MAX_FILE_BYTES:
        raise UnsafeModelFileError(
            f"{what} file {str(path)!r} has {size} bytes, more than the {MAX_FILE_BYTES} read from a model file"
        )
    text = path.read_bytes()
    try:
        return fromstring(text, forbid_dtd=True, forbid_entities=True, forbid_external=True)
    except DefusedXmlException as exc:
        raise UnsafeModelFileError(
            f"{what} file {str(path)!r} is refused: {type(exc).__name__} ({exc}); model files need no "
            "DTD or entities, and expanding them is how an XML file exhausts memory"
        ) from None
    except ParseError as exc:
        raise ModelLoadError(f"cannot read {what} {str(path)!r}: {exc}") from None


def inside(path: Path, folder: Path) -> bool:
    """Whether ``path`` (resolved, symbolic links followed) lies in ``folder``."""
    try:
        path.resolve().relative_to(folder.resolve())
    except ValueError:
        return False
    return True


def named_file(base: Path, name: str, folder: Path, allow_outside: bool, what: str) -> Path:
    """The file ``name`` (relative to ``base``, or absolute) a model names, checked to lie in
    ``folder`` (the model's folder) unless ``allow_outside``.

    Raises:
        UnsafeModelFileError: the path leaves ``folder`` and ``allow_outside`` is False.
    """
    path = Path(name) if Path(name).is_absolute() else base / name
    if not allow_outside and not inside(path, folder):
        raise UnsafeModelFileError(
            f"{what} {name!r} resolves to {str(path.resolve())!r}, outside the model's folder "
            f"{str(folder.resolve())!r}; pass allow_outside=True to read files outside it"
        )
    return path


def read_document(path: str | Path, allow_outside: bool = False) -> MJCFDocument:
    """Read an MJCF file and the files it includes (see the module notes).

    Args:
        path: the main ``.xml`` file.
        allow_outside: allow ``<include>`` and asset paths outside the main file's folder.

    Raises:
        UnsafeModelFileError: unsafe XML, a path out of the folder, too many includes.
        ModelLoadError: a file is missing or malformed, the root is not ``<mujoco>``,
            an ``<include>`` has no ``file``, or a class is used that is not defined.
    """
    path = Path(path)
    root = parse_xml_file(path)
    if root.tag != "mujoco":
        raise ModelLoadError(f"{str(path)!r} is not an MJCF file: its root element is <{root.tag}>, not <mujoco>")
    folder = path.resolve().parent
    doc = MJCFDocument(path, root, [path])
    _expand_includes(doc, root, folder, allow_outside, [path.resolve()])
    _merge_sections(root)
    _check_asset_paths(doc, folder, allow_outside)
    doc.classes = _default_classes(root)
    return doc


def _expand_includes(doc: MJCFDocument, element: Element, folder: Path, allow_outside: bool, stack: list[Path]) -> None:
    children = []
    for child in list(element):
        if child.tag != "include":
            _expand_includes(doc, child, folder, allow_outside, stack)
            children.append(child)
            continue
        name = child.get("file")
        if not name:
            raise ModelLoadError(f"MJCF {str(doc.path)!r}: an <include> has no file attribute")
        target = named_file(folder, name, folder, allow_outside, "<include> file")
        if target.resolve() in stack:
            raise UnsafeModelFileError(
                f"MJCF {str(doc.path)!r}: <include> file {name!r} includes itself (directly or through other files)"
            )
        if len(doc.files) >= MAX_INCLUDES:
            raise UnsafeModelFileError(f"MJCF {str(doc.path)!r} includes more than {MAX_INCLUDES} files")
        included = parse_xml_file(target, "MJCF <include>")
        if included.tag != "mujoco":
            raise ModelLoadError(f"MJCF <include> file {str(target)!r}: root element is <{included.tag}>, not <mujoco>")
        doc.files.append(target)
        _expand_includes(doc, included, folder, allow_outside, stack + [target.resolve()])
        children.extend(included)
    element[:] = children


MERGED_SECTIONS = ("worldbody", "asset", "actuator", "keyframe", "contact", "equality", "tendon", "sensor")
"""Top-level sections MuJoCo reads as one when a model has several (a ``scene.xml`` that
includes the robot's file and adds its own ``<worldbody>`` with a floor)."""


def _merge_sections(root: Element) -> None:
    """Move the children of repeated `MERGED_SECTIONS` into the first of each (Pinocchio
    reads only one ``<worldbody>``: a scene file's floor would hide the robot)."""
    for tag in MERGED_SECTIONS:
        sections = root.findall(tag)
        for extra in sections[1:]:
            sections[0].extend(list(extra))
            root.remove(extra)


def _check_asset_paths(doc: MJCFDocument, folder: Path, allow_outside: bool) -> None:
    """Refuse asset files (meshes, textures, height fields) that lie outside the model's
    folder. They are never opened here; the check keeps a later reader (a viewer) in it."""
    asset_files(doc.root, folder, allow_outside)


def asset_files(root: Element, folder: Path, allow_outside: bool = True) -> list[tuple[str, Path]]:
    """``(tag, path)`` of every asset file the model names (``<mesh file=...>``, ...), resolved
    as MuJoCo resolves them (``compiler`` ``meshdir``/``texturedir``, else ``assetdir``).

    Raises:
        UnsafeModelFileError: a path leaves ``folder`` and ``allow_outside`` is False.
    """
    return [(element.tag, path) for element, path in asset_elements(root, folder, allow_outside)]


def asset_elements(root: Element, folder: Path, allow_outside: bool = True) -> list[tuple[Element, Path]]:
    """``(element, path)`` of every asset element that names a file (`asset_files`)."""
    compiler = {}
    for element in root.iter("compiler"):
        compiler.update(element.attrib)
    files = []
    for asset in root.iter("asset"):
        for element in asset:
            name = element.get("file")
            if element.tag not in _ASSET_FILE_TAGS or not name:
                continue
            kind = "mesh" if element.tag in ("mesh", "skin") else "texture" if element.tag == "texture" else ""
            sub = compiler.get(f"{kind}dir") if kind else None
            sub = sub if sub is not None else compiler.get("assetdir", "")
            files.append((element, named_file(folder / sub, name, folder, allow_outside, f"<{element.tag}> file")))
    return files


def mesh_name(mesh: Element) -> str:
    """A ``<mesh>``'s name: its ``name``, else its file's name without folder and extension
    (MuJoCo's rule)."""
    return mesh.get("name") or Path(mesh.get("file", "")).stem


def _default_classes(root: Element) -> dict[str, dict[str, dict[str, str]]]:
    classes: dict[str, dict[str, dict[str, str]]] = {}

    def walk(element: Element, name: str, inherited: dict[str, dict[str, str]]) -> None:
        own = {tag: dict(attrs) for tag, attrs in inherited.items()}
        for child in element:
            if child.tag != "default":
                own.setdefault(child.tag, {}).update(child.attrib)
        classes[name] = own
        for child in element:
            if child.tag == "default":
                walk(child, child.get("class", "main"), own)

    classes["main"] = {}
    for top in root.findall("default"):
        walk(top, top.get("class", "main"), classes.get("main", {}))
    return classes


def resolve(doc: MJCFDocument) -> Element:
    """A copy of the model's root with every body-tree element's class attributes inline
    (see the module notes).

    Raises:
        ModelLoadError: an element names a class that is not defined (the classes are listed).
    """
    root = copy.deepcopy(doc.root)
    for world in root.findall("worldbody"):
        _inline(doc, world, "main")
    for asset in root.findall("asset"):  # a class's mesh scale or reference frame (mesh inertia)
        for element in asset.findall("mesh"):
            _inline_one(doc, element, "main")
    for section in root.findall("actuator"):  # a class's dyntype on <general> (actuator dynamics)
        for element in section:
            if element.tag == "general":
                _inline_one(doc, element, "main")
    return root


def _inline(doc: MJCFDocument, body: Element, childclass: str) -> None:
    for element in body:
        if element.tag in ("body", "frame"):
            _inline(doc, element, element.get("childclass", childclass))
            continue
        if element.tag in BODY_TREE_TAGS:
            _inline_one(doc, element, childclass)


def _inline_one(doc: MJCFDocument, element: Element, childclass: str) -> None:
    """Write the attributes ``element``'s class gives it (``class=``, else ``childclass``) inline."""
    name = element.get("class", childclass)
    if name not in doc.classes:
        raise ModelLoadError(
            f"MJCF {str(doc.path)!r}: <{element.tag} name={element.get('name')!r}> uses "
            f"class {name!r}, which is not defined; classes: {', '.join(sorted(doc.classes))}"
        )
    given = set(element.attrib)
    for key, value in doc.classes[name].get(element.tag, {}).items():
        if key in given or key == "class":
            continue
        if "fromto" in given and key in _FROMTO_REPLACES:
            continue
        if key in _ORIENTATION and given & set(_ORIENTATION):
            continue
        element.set(key, value)


def bodies(root: Element):
    """Every ``<body>`` of ``<worldbody>``, depth first in file order, with its parent
    (``None`` for a top-level body)."""

    def walk(element, parent):
        for child in element.findall("body"):
            yield child, parent
            yield from walk(child, child)

    for world in root.findall("worldbody"):
        yield from walk(world, None)


def compiler_option(root: Element, key: str, default: str) -> str:
    """The last value ``<compiler key=...>`` sets (MuJoCo merges repeated compiler elements)."""
    value = default
    for element in root.iter("compiler"):
        value = element.get(key, value)
    return value


def numbers(text: str | None, default: tuple[float, ...] = ()) -> tuple[float, ...]:
    """The numbers of an attribute (``"0 0 1"``), ``default`` when absent.

    Raises:
        ModelLoadError: a token is not a number.
    """
    if text is None:
        return default
    try:
        return tuple(float(x) for x in text.split())
    except ValueError:
        raise ModelLoadError(f"MJCF attribute value {text!r} is not a list of numbers") from None
