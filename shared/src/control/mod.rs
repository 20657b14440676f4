//! The rig controller, hardware-free: the drive's sine generator, the impact detector, the
//! online regime meter, the fault checks, the tracking hill climber, the console parser and the
//! state machine that ties them together. The firmware calls it from its RTIC tasks through the
//! traits of [`crate::hal`]; host-sim runs the same code against a simulated rig.
//!
//! The console: [`Link`] (bytes ↔ lines, bounded queues) → [`serve::answer`] (one answer per
//! line); [`Capture`] records drop tests at [`CAPTURE_RATE_HZ`].
//!
//! Data flow per force sample: ADC code → [`SensorChain`] (N) → [`ImpactDetector`] →
//! [`RegimeMeter`] (per excitation cycle) → [`HillClimber`] (per evaluation) →
//! [`SineGenerator`] → DAC code.

pub mod capture;
pub mod config;
pub mod console;
pub mod controller;
pub mod detector;
pub mod faults;
pub mod fixed;
pub mod health;
pub mod link;
pub mod meter;
pub mod prediction;
pub mod serve;
pub mod sine;
pub mod status;
pub mod tracker;

pub use capture::{CAPTURE_RATE_HZ, Capture, CaptureCommand, CaptureState, CaptureStatus};
pub use config::{
    ControllerConfig, DetectorSettings, DriveChain, FaultSettings, Limits, SAMPLE_PERIOD_US,
    SAMPLE_RATE_HZ, SensorChain, TrackSettings,
};
pub use console::{Command, Line, LineBuffer, ParseError, Request, RxError, parse};
pub use controller::Controller;
pub use detector::{DetectedImpact, ImpactDetector};
pub use faults::{Fault, SensorMonitor};
pub use fixed::{Fixed, parse_decimal};
pub use health::{Health, HealthCheck};
pub use link::{Link, LinkStats, PendingLine};
pub use meter::RegimeMeter;
pub use prediction::{Prediction, predict};
pub use serve::{Answer, AnswerError, BoardInfo, Direct, RigAccess, answer};
pub use sine::{DriveSample, SineGenerator, sin_turn};
pub use status::{
    AsyncKind, AsyncRecord, CommandError, CycleTelemetry, Event, ModelRequest, ModelStatus, Reply,
    State, Status,
};
pub use tracker::HillClimber;
