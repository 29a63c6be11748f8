//! The integration tests of chronomap-multimap, one module per part, in one test binary:
//! door passages on ray-cast scans, the map graph and its uncertainty, the optimiser, and the
//! real Málaga 2006 loop.

mod door;
mod graph;
mod malaga;
mod optimize;
