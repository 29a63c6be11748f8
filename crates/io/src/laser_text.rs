//! 2-D laser scans, odometry and keyframe poses as text (the format of the bundled Málaga log).
