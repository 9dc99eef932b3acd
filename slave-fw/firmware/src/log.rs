//! Logging: `defmt` over RTT with the `defmt` feature, nothing otherwise (the arguments are still
//! type-checked, so no variable turns "unused" without the feature).

#[cfg(feature = "defmt")]
macro_rules! log_info {
    ($($t:tt)*) => { defmt::info!($($t)*) };
}

#[cfg(not(feature = "defmt"))]
macro_rules! log_info {
    ($fmt:literal $(, $arg:expr)* $(,)?) => {{ $( let _ = &$arg; )* }};
}

#[cfg(feature = "defmt")]
macro_rules! log_warn {
    ($($t:tt)*) => { defmt::warn!($($t)*) };
}

#[cfg(not(feature = "defmt"))]
macro_rules! log_warn {
    ($fmt:literal $(, $arg:expr)* $(,)?) => {{ $( let _ = &$arg; )* }};
}

pub(crate) use {log_info, log_warn};
