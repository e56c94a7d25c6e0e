//! The physics twin.
