//! Log macros for the core.
//!
//! On a target with a defmt logger (feature `defmt`) they go to defmt; on a host they go to
//! the `log` crate, which the shell routes to stderr. defmt cannot run on a Linux host, hence
//! the indirection. Keep the arguments to plain `{}` placeholders so both back ends accept
//! them.

#[cfg(feature = "defmt")]
#[macro_export]
macro_rules! sf_warn {
    ($($arg:tt)*) => { defmt::warn!($($arg)*) };
}

#[cfg(not(feature = "defmt"))]
#[macro_export]
macro_rules! sf_warn {
    ($($arg:tt)*) => { log::warn!($($arg)*) };
}

#[cfg(feature = "defmt")]
#[macro_export]
macro_rules! sf_info {
    ($($arg:tt)*) => { defmt::info!($($arg)*) };
}

#[cfg(not(feature = "defmt"))]
#[macro_export]
macro_rules! sf_info {
    ($($arg:tt)*) => { log::info!($($arg)*) };
}
