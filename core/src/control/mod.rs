//! Control (see the modules).
