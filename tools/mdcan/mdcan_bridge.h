/// @file mdcan_bridge.h
/// `mdcan bridge --serial PATH --bus SPEC`: md_link packets on a serial line
/// <-> frames on a bus (docs/pil.md).
#ifndef MDCAN_BRIDGE_H
#define MDCAN_BRIDGE_H

/// Runs the bridge until SIGINT/SIGTERM or the serial side closes. argv[1] is
/// "bridge". Exit status: 0 ok, 1 a frame was lost or a side failed, 2 usage,
/// 3 a side could not be opened.
int mdcan_bridge_main(int argc, char **argv);

#endif
