//! The tests of chronomap-io on the bundled real files and on hostile input, one module per
//! format, in one test binary.

mod common;

mod bt_log;
mod bt_xml;
mod copa_init;
mod events;
mod grid_format;
mod hostile_maps;
mod matrix;
mod model_file;
mod model_invariants;
mod navmap;
mod properties;
mod text;
mod topo_files;
mod tracks;
