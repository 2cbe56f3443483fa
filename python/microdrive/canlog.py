"""Session frame logs (candump -L lines, `frames.log` / `candump.log`) read by DBC message name.

    from microdrive import canlog
    for m in canlog.messages("out/candump.log", names={"TLM_STATUS", "TLM_CYCLE"}):
        print(m.t, m.name, m.signals["Electrode"])

A line is `(<seconds>) <iface> <hex id>#<hex data>` (classic CAN) or `...##<flags nibble><hex data>` (CAN FD);
any other line is skipped. Messages are decoded with cantools from common/protocol/microdrive.dbc (raw
values of enumerations, scaled physical values), the one description of the bus the firmware's packing
code is generated from. cantools comes from requirements.txt (scripts/setup-venv.sh installs both).
"""
import os
from typing import Dict, Iterable, Iterator, NamedTuple, Optional

# The package is installed editable from python/ of the checkout (scripts/setup-venv.sh).
DBC = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "common",
                   "protocol", "microdrive.dbc")

_DBS: Dict[str, object] = {}


class Frame(NamedTuple):
    t: float          # the log's timestamp, s
    frame_id: int
    name: Optional[str]  # the DBC message's name, None for an id the DBC does not define
    data: bytes


class Message(NamedTuple):
    t: float
    frame_id: int
    name: str
    signals: Optional[dict]  # None when the data does not decode as the message
    data: bytes


def load_dbc(path: Optional[str] = None):
    """The cantools database of `path` (default: the project's DBC), loaded once per path."""
    path = os.path.abspath(path or DBC)
    if path not in _DBS:
        import cantools

        _DBS[path] = cantools.database.load_file(path, strict=False)
    return _DBS[path]


def parse_line(line: str):
    """(t, frame id, data) of one candump -L line, or None if it is not a frame line."""
    parts = line.split()
    if len(parts) < 3 or not parts[0].startswith("(") or "#" not in parts[2]:
        return None
    cid, _, data = parts[2].partition("#")
    if data.startswith("#"):
        data = data[2:]  # FD: "##<flags nibble><data>"
    try:
        return float(parts[0].strip("()")), int(cid, 16), bytes.fromhex(data)
    except ValueError:
        return None


def _ids_of(db, names: Iterable[str]) -> Dict[int, str]:
    return {db.get_message_by_name(n).frame_id: n for n in names}


def frames(path: str, names: Optional[Iterable[str]] = None, db=None) -> Iterator[Frame]:
    """Every frame of the log in order (only the named messages with `names`), undecoded."""
    db = db or load_dbc()
    wanted = _ids_of(db, names) if names is not None else None
    prefixes = tuple(f"{i:03X}#" for i in wanted) if wanted is not None else None
    with open(path, "r", errors="replace") as f:
        for line in f:
            if prefixes is not None:  # cheap test first: logs are mostly REC_DATA
                parts = line.split(None, 3)
                if len(parts) < 3 or not parts[2].startswith(prefixes):
                    continue
            r = parse_line(line)
            if r is None:
                continue
            t, fid, data = r
            if wanted is not None:
                yield Frame(t, fid, wanted[fid], data)
                continue
            try:
                name = db.get_message_by_frame_id(fid).name
            except KeyError:
                name = None
            yield Frame(t, fid, name, data)


def decode(db, frame: Frame) -> Optional[dict]:
    """The frame's signals (raw enumeration values, scaled), or None if it does not decode."""
    try:
        return db.get_message_by_frame_id(frame.frame_id).decode(frame.data, decode_choices=False, scaling=True)
    except Exception:  # a malformed frame (wrong length, bad mux) is no message
        return None


def messages(path: str, names: Optional[Iterable[str]] = None, db=None, undecodable: bool = False) -> Iterator[Message]:
    """The log's messages the DBC defines (only the named ones with `names`), decoded, in order.
    A frame whose data does not decode is skipped, or yielded with signals None if `undecodable`."""
    db = db or load_dbc()
    for fr in frames(path, names, db):
        if fr.name is None:
            continue
        sig = decode(db, fr)
        if sig is not None or undecodable:
            yield Message(fr.t, fr.frame_id, fr.name, sig, fr.data)
