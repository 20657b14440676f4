//! End-to-end tests across the workspace crates live in `tests/`: the firmware's on-target
//! selection path (`shared`, sequential, no allocation) against the desktop's parallel one
//! (`host-sim`), and the thesis' reported behaviour at the main job's operating point.
