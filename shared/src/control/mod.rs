//! The rig controller, hardware-free and without text: the drive's sine generator, the impact
//! detector, the online regime meter, the fault checks, the tracking hill climber and the state
//! machine that ties them together. It takes and returns types ([`Command`], [`Reply`],
//! [`Status`], [`AsyncRecord`]); the console ([`crate::console`]) maps text to and from them.
//! The firmware calls it from its RTIC tasks through the traits of [`crate::hal`]; host-sim runs
//! the same code against a simulated rig.
//!
//! Data flow per force sample: ADC code → [`SensorChain`] (N) → [`ImpactDetector`] →
//! [`RegimeMeter`] (per excitation cycle) → [`HillClimber`] (per evaluation) →
//! [`SineGenerator`] → DAC code.

pub mod calibration;
pub mod command;
pub mod config;
pub mod controller;
pub mod detector;
pub mod faults;
pub mod meter;
pub mod model_id;
pub mod prediction;
pub mod rest_probe;
pub mod settings;
pub mod sine;
pub mod status;
pub mod tracker;

pub use calibration::{CalibField, Calibration};
pub use command::{Command, CommandError, Reply};
pub use config::{
    ControllerConfig, DetectorSettings, DriveChain, FaultSettings, Limits, MAX_GAP_MM,
    MAX_LINK_TIMEOUT_S, MIN_LINK_TIMEOUT_S, SAMPLE_PERIOD_US, SAMPLE_RATE_HZ, SensorChain,
    TrackSettings,
};
pub use controller::Controller;
pub use detector::{DetectedImpact, ImpactDetector};
pub use faults::{Fault, SensorMonitor};
pub use meter::RegimeMeter;
pub use model_id::{ModelId, ModelSource};
pub use prediction::{Prediction, predict};
pub use rest_probe::{RestProbe, RestStats};
pub use settings::{Draft, Settings, SettingsError};
pub use sine::{DriveSample, SineGenerator, sin_turn};
pub use status::{
    AsyncKind, AsyncRecord, CycleTelemetry, Event, MAX_FORCE_VS_MODEL_PCT, ModelRequest,
    ModelStatus, PeakForce, State, Status, Target,
};
pub use tracker::HillClimber;

/// `x` limited to `lo ..= hi` without `f32::clamp`'s panic (when `lo > hi` or either is NaN):
/// `hi` wins over `lo`, and a NaN `x` gives `lo`. Used on the control path, which must not panic.
pub fn within(x: f32, lo: f32, hi: f32) -> f32 {
    x.max(lo).min(hi)
}
