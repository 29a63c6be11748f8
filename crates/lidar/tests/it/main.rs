//! The integration tests of `chronomap-lidar`, one module per subject, in one test binary (one
//! link instead of one per file): the real Málaga keyframes, and the scikit-learn oracle of the
//! AdaBoost classifier.

mod malaga;
mod sklearn_adaboost;
