#!/usr/bin/env python3
"""The controller's receive rules and docs/protocol.md cover every DBC frame.

    test_fw_dbc_coverage.py DBC firmware/app/md_node.c docs/protocol.md

md_node.c validates frames against a table RX_RULES with one row per DBC
message: {MD_CAN_<NAME>_FRAME_ID, MD_CAN_<NAME>_LENGTH, <fd>, <role>}. A frame
added to the DBC without a row would be counted as an unknown id, so this test
fails until the row (with the DBC's FD flag, and RX_OWN exactly for the frames
the controller sends) exists, and until the frame is named in docs/protocol.md.
"""
import re
import sys

import cantools


def main():
    dbc, node_c, doc = sys.argv[1:4]
    db = cantools.database.load_file(dbc)
    src = open(node_c, encoding="utf-8").read()
    text = open(doc, encoding="utf-8").read()
    rows = dict((m.group(1), (m.group(2), m.group(3))) for m in re.finditer(
        r"\{MD_CAN_(\w+)_FRAME_ID, MD_CAN_\1_LENGTH, (true|false), (RX_CONSUME|RX_OWN)\}", src))
    errors = []
    for msg in db.messages:
        name = msg.name.upper()
        if name not in rows:
            errors.append(f"{msg.name} (0x{msg.frame_id:03X}) has no RX_RULES row in {node_c}")
            continue
        fd, role = rows.pop(name)
        if (fd == "true") != bool(msg.is_fd):
            errors.append(f"{msg.name}: RX_RULES says fd={fd}, the DBC says is_fd={msg.is_fd}")
        own = "CTRL" in msg.senders
        if (role == "RX_OWN") != own:
            errors.append(f"{msg.name}: RX_RULES role {role}, but senders are {msg.senders}")
        if msg.name not in text and not re.search(msg.name.rsplit("_", 1)[0] + r"\b", text):
            errors.append(f"{msg.name} is not mentioned in {doc}")
    errors += [f"RX_RULES row {n} is not in the DBC" for n in rows]
    for e in errors:
        print("FAIL:", e)
    if errors:
        return 1
    print(f"test_fw_dbc_coverage: OK ({len(db.messages)} frames)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
