//! The model: rig parameters → contact law + suspension → the switch-model vector field.
//!
//! - [`rig`]: the identified rig parameters (thesis Tables 3.1–3.3) as serde structs with presets.
//! - [`edit`]: a model edited field by field (the console's `model …`), validated as a whole.
//! - [`encoding`]: a model's canonical bytes and their hash (what the board and the desktop
//!   compare to know they hold the same model).
//! - [`contact`]: the four contact laws, Eq. (3-2)–(3-5).
//! - [`switch`]: Leine's switch model with the indicator functions `h_α`, `h_β`, Eq. (3-19)–(3-29).
//! - [`hammer`]: a rig compiled for one gap and excitation frequency: the right-hand side of
//!   Eq. (3-25)–(3-29) (wires) and (3-36)–(3-39) (beam springs) in the float type `T`.

pub mod contact;
pub mod edit;
pub mod encoding;
pub mod hammer;
pub mod rig;
pub mod switch;

pub use contact::{ContactLaw, ContactLawKind};
pub use edit::{EditError, ModelEdit, ModelField, SuspensionKind};
pub use encoding::{PARAMS_BYTES, params_bytes, params_hash};
pub use hammer::Hammer;
pub use rig::{MAX_DAMPING_RATIO, RigId, RigParams, Suspension};
pub use switch::{Region, SwitchBands};
