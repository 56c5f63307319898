"""The binary messages of dynval's high-rate MCAP topics (samples, raw frames, features,
residuals): protobuf messages (schema encoding "protobuf": a FileDescriptorSet, which Foxglove
and Lichtblick decode with protobufjs and plot field by field), written at a fixed layout so
that a logger builds a block of them as one numpy record array (mcap_writer).

Fixed layout: every field is written, in field-number order, each at a fixed width: fixed32 /
sfixed32 / fixed64 / double fields, enums and bools as a one-byte varint (values below 128),
bytes with a one-byte length. That is valid protobuf wire format (a decoder accepts fields at
their default value), so any protobuf reader reads it; test_mcap_schema checks the bytes
against the protobuf library's own parse. A missing sample is value NaN (a plot gap)."""
from __future__ import annotations

from functools import cache
from typing import Any

import numpy as np

PACKAGE = "dynval"
#: the sequence verdicts (dv_seq_verdict_t order, bus.SEQ_VERDICTS) as a protobuf enum
VERDICT_ENUM = "Verdict"

# kind -> (numpy dtype, wire type, FieldDescriptorProto.Type)
_KINDS: dict[str, tuple[str, int, int]] = {
    "fixed32": ("<u4", 5, 7), "sfixed32": ("<i4", 5, 15), "fixed64": ("<u8", 1, 6),
    "double": ("<f8", 1, 1), "bool": ("u1", 0, 8), "enum": ("u1", 0, 14), "bytes": ("", 2, 12)}

#: message name -> [(field, number, kind)], numbers in order from 1 (one-byte tags).
#: Sample: one sample, index since START (its log time is the test's clock at index / fs),
#: value = raw * lsb in the channel's unit (NaN: missing), the frame's sequence verdict (its
#: raw counts and counter are in the frame on /can/raw). CanFrame: a frame as received.
#: Feature, Residual: DV_FEATURE, DV_RESID; value the binary32 as double, bits its bits.
MESSAGES: dict[str, list[tuple[str, int, str]]] = {
    "Sample": [("channel", 1, "fixed32"), ("index", 2, "fixed64"), ("value", 3, "double"),
               ("verdict", 4, "enum")],
    "CanFrame": [("id", 1, "fixed32"), ("extended", 2, "bool"), ("dlc", 3, "fixed32"),
                 ("data", 4, "bytes")],
    "Feature": [("channel", 1, "fixed32"), ("feat_id", 2, "fixed32"), ("index", 3, "fixed32"),
                ("value", 4, "double"), ("bits", 5, "fixed32")],
    "Residual": [("channel", 1, "fixed32"), ("flags", 2, "fixed32"), ("step", 3, "fixed32"),
                 ("value", 4, "double"), ("bits", 5, "fixed32")],
}
def full_name(msg: str) -> str:
    return f"{PACKAGE}.{msg}"


@cache
def descriptor_set() -> bytes:
    """The FileDescriptorSet of dynval.proto (every message), the schema data of each."""
    from google.protobuf import descriptor_pb2

    from dynval import bus

    fd = descriptor_pb2.FileDescriptorProto(name="dynval.proto", package=PACKAGE,
                                            syntax="proto3")
    en = fd.enum_type.add(name=VERDICT_ENUM)
    for i, v in enumerate(bus.SEQ_VERDICTS):
        en.value.add(name=v, number=i)
    for name, fields in MESSAGES.items():
        m = fd.message_type.add(name=name)
        for fname, num, kind in fields:
            f = m.field.add(name=fname, number=num, type=_KINDS[kind][2],
                            label=descriptor_pb2.FieldDescriptorProto.LABEL_OPTIONAL)
            if kind == "enum":
                f.type_name = f".{PACKAGE}.{VERDICT_ENUM}"
    return bytes(descriptor_pb2.FileDescriptorSet(file=[fd]).SerializeToString())


@cache
def payload_fields(msg: str, bytes_len: int = 8) -> tuple[tuple[Any, ...], ...]:
    """The packed numpy fields of a message's fixed layout: per field a tag byte ("_t<n>"),
    for bytes a length byte ("_n<n>"), then the value under the field's name."""
    out: list[tuple[Any, ...]] = []
    for fname, num, kind in MESSAGES[msg]:
        out.append((f"_t{num}", "u1"))
        if kind == "bytes":
            out += [(f"_n{num}", "u1"), (fname, ("u1", (bytes_len,)))]
        else:
            out.append((fname, _KINDS[kind][0]))
    return tuple(out)


def fill_tags(block: np.ndarray, msg: str, bytes_len: int = 8) -> None:
    """Write the constant tag (and length) bytes of a block of msg records."""
    for _fname, num, kind in MESSAGES[msg]:
        block[f"_t{num}"] = (num << 3) | _KINDS[kind][1]
        if kind == "bytes":
            block[f"_n{num}"] = bytes_len


# ---- reading ---------------------------------------------------------------------------------
class ProtobufDecoder:
    """Decode the messages of one protobuf schema (any FileDescriptorSet, dynval's or not)
    into dicts with every field of the message: enums by name, bytes as hex (the JSON
    layout's spelling of a frame's data), nested messages as dicts."""

    def __init__(self, schema_name: str, schema_data: bytes) -> None:
        from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

        fds = descriptor_pb2.FileDescriptorSet.FromString(schema_data)
        pool = descriptor_pool.DescriptorPool()
        for f in fds.file:
            pool.Add(f)
        self.desc = pool.FindMessageTypeByName(schema_name)
        self.cls: Any = message_factory.GetMessageClass(self.desc)

    def __call__(self, data: bytes) -> dict[str, Any]:
        return _to_dict(self.cls.FromString(data))


def _to_dict(msg: Any) -> dict[str, Any]:
    from google.protobuf.descriptor import FieldDescriptor as F

    out: dict[str, Any] = {}
    for f in msg.DESCRIPTOR.fields:
        v = getattr(msg, f.name)
        if f.type == F.TYPE_MESSAGE:
            v = [_to_dict(x) for x in v] if _repeated(f) else _to_dict(v)
        elif f.type == F.TYPE_ENUM and not _repeated(f):
            e = f.enum_type.values_by_number.get(v)
            v = e.name if e is not None else v
        elif f.type == F.TYPE_BYTES and not _repeated(f):
            v = bytes(v).hex()
        elif _repeated(f):
            v = list(v)
        out[f.name] = v
    return out


def _repeated(f: Any) -> bool:
    return bool(f.is_repeated)
