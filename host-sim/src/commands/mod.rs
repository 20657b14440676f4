//! One module per command.

pub mod points;
pub mod response;
pub mod select;
pub mod simulate;
