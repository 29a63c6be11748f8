//! 3-D point clouds as PLY files (ASCII and binary).
