"""UAVObject definitions loaded from dRonin-style XML, their ids and their wire packing.

The object id is the firmware's own shift-add-XOR hash over the definition (docs/uavtalk.md,
"Object ids"), so a real board and this code agree on ids without a hard-coded table.
"""

from __future__ import annotations

import os
import struct
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from importlib.resources import files
from pathlib import Path

from onboard.uavtalk import generations

# Type index (hashed) -> (xml name, struct code, size in bytes), as the firmware numbers them.
FIELD_TYPES: tuple[tuple[str, str, int], ...] = (
    ("int8", "b", 1),
    ("int16", "h", 2),
    ("int32", "i", 4),
    ("uint8", "B", 1),
    ("uint16", "H", 2),
    ("uint32", "I", 4),
    ("float", "f", 4),
    ("enum", "B", 1),
)
TYPE_INDEX = {name: index for index, (name, _, _) in enumerate(FIELD_TYPES)}
ENUM_TYPE = TYPE_INDEX["enum"]
FLOAT_TYPE = TYPE_INDEX["float"]
MAX_OBJECT_BYTES = 243  # Largest payload a UAVTalk packet can carry (docs/uavtalk.md).
UPDATE_MODES = ("manual", "periodic", "onchange", "throttled")

METADATA_STRUCT = struct.Struct("<BHHH")  # flags, flight period, GCS period, logging period


class DefinitionError(ValueError):
    """An object definition file that cannot be loaded."""


class EncodeError(ValueError):
    """Field values that do not fit the object definition."""


@dataclass(frozen=True)
class FieldDef:
    name: str
    type_index: int
    elements: int
    element_names: tuple[str, ...] = ()
    options: tuple[str, ...] = ()
    parent: str | None = None
    # Index of each option in the root parent's list (dRonin hashes gaps, see object_id).
    option_values: tuple[int, ...] = ()
    defaults: tuple[str, ...] = ()

    @property
    def type_name(self) -> str:
        return FIELD_TYPES[self.type_index][0]

    @property
    def size(self) -> int:
        return FIELD_TYPES[self.type_index][2]

    @property
    def is_enum(self) -> bool:
        return self.type_index == ENUM_TYPE

    def enum_value(self, option: str | int) -> int:
        """Wire value of an enum option given by name (or already as a number)."""
        if isinstance(option, bool) or not isinstance(option, (str, int)):
            raise EncodeError(f"{self.name}: enum value must be an option name, got {option!r}")
        if isinstance(option, int):
            if option not in self.option_values:
                raise EncodeError(f"{self.name}: {option} is not a valid option value")
            return option
        try:
            return self.option_values[self.options.index(option)]
        except ValueError:
            raise EncodeError(
                f"{self.name}: unknown option {option!r} (one of {', '.join(self.options)})"
            ) from None

    def enum_name(self, value: int) -> str | int:
        """Option name of a wire value; the number itself if the value is out of range."""
        try:
            return self.options[self.option_values.index(value)]
        except ValueError:
            return value


@dataclass(frozen=True)
class UpdatePolicy:
    mode: str
    period_ms: int
    acked: bool


@dataclass(frozen=True)
class ObjectDef:
    name: str
    settings: bool
    single_instance: bool
    fields: tuple[FieldDef, ...]  # in wire order
    flight: UpdatePolicy = UpdatePolicy("manual", 0, False)
    gcs: UpdatePolicy = UpdatePolicy("manual", 0, False)
    logging: UpdatePolicy = UpdatePolicy("manual", 0, False)
    description: str = ""
    id: int = 0
    _struct: struct.Struct = field(default=struct.Struct("<"), repr=False, compare=False)

    @property
    def size(self) -> int:
        return self._struct.size

    @property
    def field_names(self) -> tuple[str, ...]:
        return tuple(f.name for f in self.fields)

    def field(self, name: str) -> FieldDef:
        for f in self.fields:
            if f.name == name:
                return f
        raise KeyError(f"{self.name} has no field {name!r}")

    def defaults(self) -> dict:
        """Field values from the XML defaults (zero / first option where none is given)."""
        values: dict = {}
        for f in self.fields:
            raw = list(f.defaults) or ([f.options[0]] if f.is_enum else ["0"])
            if len(raw) == 1 and f.elements > 1:
                raw = raw * f.elements
            items = [_parse_default(f, text) for text in raw[: f.elements]]
            values[f.name] = items[0] if f.elements == 1 else items
        return values

    def __post_init__(self) -> None:
        # Per-field plan compiled once: (name, elements, option -> value, value -> option).
        plan = tuple(
            (
                f.name,
                f.elements,
                dict(zip(f.options, f.option_values, strict=True)) if f.is_enum else None,
                dict(zip(f.option_values, f.options, strict=True)) if f.is_enum else None,
            )
            for f in self.fields
        )
        object.__setattr__(self, "_plan", plan)

    def pack(self, values: Mapping[str, object]) -> bytes:
        """Payload bytes for a complete set of field values (enums by option name)."""
        flat: list[object] = []
        append, extend = flat.append, flat.extend
        for name, elements, to_value, _ in self._plan:  # type: ignore[attr-defined]
            try:
                value = values[name]
            except KeyError:
                raise EncodeError(f"{self.name}: field {name} is missing") from None
            if elements == 1:
                if to_value is not None:
                    value = to_value.get(value) if isinstance(value, str) else None  # type: ignore[assignment]
                    if value is None:
                        value = self.field(name).enum_value(values[name])  # type: ignore[arg-type]
                append(value)
                continue
            if not isinstance(value, (list, tuple)) or len(value) != elements:
                raise EncodeError(f"{self.name}.{name}: expected {elements} elements")
            if to_value is not None:
                f = self.field(name)
                extend(f.enum_value(item) for item in value)
            else:
                extend(value)
        try:
            return self._struct.pack(*flat)
        except struct.error as exc:
            raise EncodeError(f"{self.name}: {exc}") from None

    def unpack(self, payload: bytes | bytearray | memoryview) -> dict:
        """Field values of a payload; enums as option names, arrays as lists."""
        flat = self._struct.unpack(payload)
        values: dict = {}
        pos = 0
        for name, elements, _, to_name in self._plan:  # type: ignore[attr-defined]
            if elements == 1:
                item = flat[pos]
                values[name] = to_name.get(item, item) if to_name is not None else item
                pos += 1
                continue
            items = flat[pos : pos + elements]
            pos += elements
            if to_name is not None:
                values[name] = [to_name.get(i, i) for i in items]
            else:
                values[name] = list(items)
        return values


def _parse_default(f: FieldDef, text: str) -> object:
    if f.is_enum:
        return text if text in f.options else f.options[0]
    if f.type_index == FLOAT_TYPE:
        return float(text)
    return int(float(text))


def update_hash(hash_: int, value: int) -> int:
    return (hash_ ^ ((hash_ << 5) + (hash_ >> 2) + value)) & 0xFFFFFFFF


def _hash_text(hash_: int, text: str) -> int:
    for byte in text.encode("latin-1"):
        hash_ = update_hash(hash_, byte)
    return hash_


def object_id(name: str, settings: bool, single_instance: bool, fields: Iterable[FieldDef]) -> int:
    """The firmware's object id: a hash of the definition with the low bit cleared (meta = id+1)."""
    h = _hash_text(0, name)
    h = update_hash(h, int(settings))
    h = update_hash(h, int(single_instance))
    for f in fields:
        h = _hash_text(h, f.name)
        h = update_hash(h, f.elements)
        h = update_hash(h, f.type_index)
        if f.is_enum:
            expected = 0
            for option, value in zip(f.options, f.option_values, strict=True):
                # Options inherited with parent= may skip values; the firmware hashes the jump.
                if value != expected:
                    h = update_hash(h, value)
                expected = value + 1
                h = _hash_text(h, option)
    return h & 0xFFFFFFFE


@dataclass
class _RawField:
    name: str
    type_index: int
    elements: int
    element_names: tuple[str, ...]
    options: tuple[str, ...]
    parent: str | None
    defaults: tuple[str, ...]


@dataclass
class _RawObject:
    name: str
    settings: bool
    single_instance: bool
    fields: list[_RawField]
    policies: dict[str, UpdatePolicy]
    description: str
    source: str


def _bool_attr(elem: ET.Element, attr: str, source: str) -> bool:
    value = elem.get(attr)
    if value not in ("true", "false"):
        raise DefinitionError(f"{source}: <{elem.tag}> {attr} must be true or false")
    return value == "true"


def _split(text: str) -> tuple[str, ...]:
    return tuple(part.strip() for part in text.split(",") if part.strip())


def _parse_field(elem: ET.Element, source: str, siblings: list[_RawField]) -> _RawField:
    name = elem.get("name")
    if not name:
        raise DefinitionError(f"{source}: a field has no name")
    clone_of = elem.get("cloneof")
    if clone_of:
        for sibling in siblings:
            if sibling.name == clone_of:
                return _RawField(**{**sibling.__dict__, "name": name})
        raise DefinitionError(f"{source}: {name} clones unknown field {clone_of}")
    type_name = elem.get("type")
    if type_name not in TYPE_INDEX:
        raise DefinitionError(f"{source}: field {name} has invalid type {type_name!r}")
    names: tuple[str, ...] = _split(elem.get("elementnames", ""))
    if not names and (listing := elem.find("elementnames")) is not None:
        names = tuple(e.text.strip() for e in listing.findall("elementname") if e.text)
    if names:
        elements = len(names)
    else:
        try:
            elements = int(elem.get("elements", "0"))
        except ValueError:
            elements = 0
        if elements <= 0:
            raise DefinitionError(f"{source}: field {name} needs elements >= 1 or elementnames")
    options: tuple[str, ...] = ()
    parent = None
    if type_name == "enum":
        parent = (elem.get("parent") or "").strip() or None
        options = _split(elem.get("options", ""))
        if not options and (listing := elem.find("options")) is not None:
            options = tuple(e.text.strip() for e in listing.findall("option") if e.text)
        if not options and parent is None:
            raise DefinitionError(f"{source}: enum field {name} has no options")
    return _RawField(
        name=name,
        type_index=TYPE_INDEX[type_name],
        elements=elements,
        element_names=names,
        options=options,
        parent=parent,
        defaults=_split(elem.get("defaultvalue", "")),
    )


def parse_definition(text: str, source: str = "<xml>") -> list[_RawObject]:
    """Parse one XML file's objects (fields still in file order, parents unresolved)."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise DefinitionError(f"{source}: {exc}") from None
    objects = []
    for obj in root.findall("object"):
        name = obj.get("name")
        if not name:
            raise DefinitionError(f"{source}: an object has no name")
        fields: list[_RawField] = []
        for elem in obj.findall("field"):
            fields.append(_parse_field(elem, source, fields))
        if not fields:
            raise DefinitionError(f"{source}: {name} has no fields")
        policies = {}
        for tag in ("telemetryflight", "telemetrygcs", "logging"):
            meta = obj.find(tag)
            if meta is None:
                raise DefinitionError(f"{source}: {name} lacks <{tag}>")
            mode = meta.get("updatemode", "")
            if mode not in UPDATE_MODES:
                raise DefinitionError(f"{source}: {name} <{tag}> has invalid updatemode {mode!r}")
            policies[tag] = UpdatePolicy(
                mode, int(meta.get("period", "0")), meta.get("acked") == "true"
            )
        description = (obj.findtext("description") or "").strip()
        settings = _bool_attr(obj, "settings", source)
        single = _bool_attr(obj, "singleinstance", source)
        objects.append(_RawObject(name, settings, single, fields, policies, description, source))
    return objects


def _parent_field(raw: dict[str, _RawObject], f: _RawField) -> _RawField:
    obj_name, _, field_name = (f.parent or "").partition(".")
    parent_obj = raw.get(obj_name)
    parent = (
        next((p for p in parent_obj.fields if p.name == field_name), None) if parent_obj else None
    )
    if parent is None:
        raise DefinitionError(f"{f.name}: unknown parent {f.parent}")
    return parent


def _chain_options(
    raw: dict[str, _RawObject], f: _RawField, seen: tuple[str, ...] = ()
) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(the field's options, the root's options) along its parent= chain. A field that
    lists no options takes its parent's list, as dRonin's uavobjectparser.cpp does, and
    its values are indexes in the root's list."""
    if f.parent is None:
        return f.options, f.options
    if f.parent in seen:
        raise DefinitionError(f"parent loop through {f.parent}")
    inherited, root = _chain_options(raw, _parent_field(raw, f), (*seen, f.parent))
    return f.options or inherited, root


def _resolve(raw: dict[str, _RawObject], f: _RawField) -> FieldDef:
    options = f.options
    values: tuple[int, ...] = tuple(range(len(options)))
    if f.type_index == ENUM_TYPE and f.parent is not None:
        options, root = _chain_options(raw, f)
        try:
            values = tuple(root.index(option) for option in options)
        except ValueError as exc:
            raise DefinitionError(f"{f.name}: option not in parent {f.parent}: {exc}") from None
    return FieldDef(
        name=f.name,
        type_index=f.type_index,
        elements=f.elements,
        element_names=f.element_names,
        options=options,
        parent=f.parent,
        option_values=values,
        defaults=f.defaults,
    )


def build_objects(raw_objects: Iterable[_RawObject]) -> list[ObjectDef]:
    raw = {obj.name: obj for obj in raw_objects}
    built = []
    for obj in raw.values():
        fields = [_resolve(raw, f) for f in obj.fields]
        # Wire order: stable sort by element size, largest first (uavobjectparser.cpp).
        fields.sort(key=lambda f: -f.size)
        fmt = "<" + "".join(FIELD_TYPES[f.type_index][1] * f.elements for f in fields)
        packer = struct.Struct(fmt)
        if packer.size > MAX_OBJECT_BYTES:
            raise DefinitionError(
                f"{obj.source}: {obj.name} is {packer.size} bytes, over {MAX_OBJECT_BYTES}"
            )
        built.append(
            ObjectDef(
                name=obj.name,
                settings=obj.settings,
                single_instance=obj.single_instance,
                fields=tuple(fields),
                flight=obj.policies["telemetryflight"],
                gcs=obj.policies["telemetrygcs"],
                logging=obj.policies["logging"],
                description=obj.description,
                id=object_id(obj.name, obj.settings, obj.single_instance, fields),
                _struct=packer,
            )
        )
    return built


def _read_folder(path: Path) -> list[_RawObject]:
    raw: list[_RawObject] = []
    for file in sorted(path.glob("*.xml")):
        raw.extend(parse_definition(file.read_text(encoding="utf-8"), str(file)))
    return raw


def _others(variants: Mapping[str, Mapping[str, ObjectDef]], generation: str) -> list[ObjectDef]:
    """Other generations' definitions of the objects that differ (decoded by id only)."""
    return [obj for per in variants.values() for key, obj in per.items() if key != generation]


def default_objects_dir() -> Path:
    """Where the XML definitions live: $SKYHIVE_UAVOBJECTS, else the package's definitions/."""
    env = os.environ.get("SKYHIVE_UAVOBJECTS")
    if env:
        return Path(env)
    return Path(str(files(__package__).joinpath("definitions")))


class ObjectRegistry:
    """All known objects, by name and by id, for one firmware generation.

    `variants` holds, per object defined differently in another generation, every
    generation's definition of it (by generation key). The agent's registry also decodes
    those other definitions by id (`also_decodes`), so it can read whichever one a board
    answers; a board (the simulator) knows only its own and NACKs the others.
    """

    def __init__(
        self,
        objects: Iterable[ObjectDef],
        *,
        also_decodes: Iterable[ObjectDef] = (),
        generation: str = generations.DEFAULT.key,
        variants: Mapping[str, Mapping[str, ObjectDef]] | None = None,
    ) -> None:
        self.by_name: dict[str, ObjectDef] = {}
        self.by_id: dict[int, ObjectDef] = {}
        self.generation = generation
        self.variants: dict[str, dict[str, ObjectDef]] = {
            name: dict(per) for name, per in (variants or {}).items()
        }
        for obj in objects:
            self._add_id(obj)
            self.by_name[obj.name] = obj
        for obj in also_decodes:
            self._add_id(obj)

    def _add_id(self, obj: ObjectDef) -> None:
        if obj.id in self.by_id and self.by_id[obj.id] is not obj:
            raise DefinitionError(f"{obj.name} and {self.by_id[obj.id].name} share id {obj.id:#x}")
        self.by_id[obj.id] = obj

    @classmethod
    def load(
        cls,
        directory: str | os.PathLike[str] | None = None,
        generation: str = generations.DEFAULT.key,
        *,
        every_generation: bool = False,
    ) -> ObjectRegistry:
        """Every *.xml file of a directory (default: default_objects_dir()) with the
        generation's own definitions from `generations/<folder>/`. With
        `every_generation` the other generations' definitions are known too: decoded by
        id, and ready for `for_generation`."""
        path = Path(directory) if directory is not None else default_objects_dir()
        common = _read_folder(path)
        if not common:
            raise DefinitionError(f"no UAVObject XML files in {path}")
        keys = [g.key for g in generations.GENERATIONS] if every_generation else [generation]
        built = {
            key: build_objects(
                common + _read_folder(path / "generations" / generations.get(key).folder)
            )
            for key in dict.fromkeys([generation, *keys])
        }
        return cls._from_generations(built, generation)

    @classmethod
    def _from_generations(
        cls, built: Mapping[str, list[ObjectDef]], generation: str
    ) -> ObjectRegistry:
        variants: dict[str, dict[str, ObjectDef]] = {}
        for key, objects in built.items():
            for obj in objects:
                variants.setdefault(obj.name, {})[key] = obj
        variants = {
            name: per for name, per in variants.items() if len({o.id for o in per.values()}) > 1
        }
        return cls(
            built[generation],
            also_decodes=_others(variants, generation),
            generation=generation,
            variants=variants,
        )

    def for_generation(self, generation: str) -> ObjectRegistry:
        """The same objects, with `generation`'s definitions used by name."""
        objects = [
            self.variants[obj.name].get(generation, obj) if obj.name in self.variants else obj
            for obj in self.by_name.values()
        ]
        return type(self)(
            objects,
            also_decodes=_others(self.variants, generation),
            generation=generation,
            variants=self.variants,
        )

    @classmethod
    def from_xml(cls, *texts: str) -> ObjectRegistry:
        raw: list[_RawObject] = []
        for index, text in enumerate(texts):
            raw.extend(parse_definition(text, f"<xml {index}>"))
        return cls(build_objects(raw))

    def __getitem__(self, name: str) -> ObjectDef:
        try:
            return self.by_name[name]
        except KeyError:
            raise KeyError(f"unknown UAVObject {name!r}") from None

    def __contains__(self, name: object) -> bool:
        return name in self.by_name

    def __iter__(self):
        return iter(self.by_name.values())

    def __len__(self) -> int:
        return len(self.by_name)


def pack_metadata(flags: int, flight_ms: int, gcs_ms: int, logging_ms: int) -> bytes:
    return METADATA_STRUCT.pack(flags, flight_ms, gcs_ms, logging_ms)


def unpack_metadata(payload: bytes) -> dict:
    flags, flight_ms, gcs_ms, logging_ms = METADATA_STRUCT.unpack(payload)
    return {
        "flags": flags,
        "flight_update_mode": UPDATE_MODES[(flags >> 4) & 3],
        "flight_period_ms": flight_ms,
        "gcs_period_ms": gcs_ms,
        "logging_period_ms": logging_ms,
    }


def metadata_for(obj: ObjectDef) -> bytes:
    """The default metadata payload of an object, as the firmware builds it from the XML."""
    flags = (
        1  # flight access readwrite
        | 2  # gcs access readwrite
        | (4 if obj.flight.acked else 0)
        | (8 if obj.gcs.acked else 0)
        | UPDATE_MODES.index(obj.flight.mode) << 4
        | UPDATE_MODES.index(obj.gcs.mode) << 6
    )
    return pack_metadata(flags, obj.flight.period_ms, obj.gcs.period_ms, obj.logging.period_ms)
