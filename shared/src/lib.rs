//! The vibro-impact hammer of the thesis (chapter 3) as a `no_std`, allocation-free library that
//! runs the same way on the rig's STM32F407 (f32) and on the desktop (f32 or f64).
//!
//! Data flows one way, and the modules follow it:
//! rig parameters → [`model`] (contact law + suspension + switch model) → [`integrate`]
//! (fixed-step RK4) → [`observe`] (impacts, Poincaré section, regime, canonical protocol) →
//! [`analysis`] (frequency response, operating-frequency selection) → [`orbit`] (periodic
//! orbits by shooting, Floquet multipliers, continuation and located bifurcations, Lyapunov
//! exponents) and [`control`] (the rig controller, without text: drive, impact detection,
//! measured regime, tracking, faults, the active model and calibration) → [`store`] (those
//! settings kept in flash) → [`console`] (the console protocol: requests, replies and records
//! as text, both directions, and the service that answers lines). Beside the loop:
//! [`capture`] (the drop-test force capture) and [`health`] (the sampling health check behind
//! the watchdog); the hardware is reached through [`hal`], and the converters' bookkeeping that
//! the firmware's interrupts run is here too, tested on the desktop: [`adc_status`] (the force
//! ADC's end of conversion and overrun) and [`capture_dma`] (the capture's DMA double buffer:
//! late service, lost blocks, re-arming). Under every layer: [`real`] (f32 or
//! f64), [`dual`] (derivatives through the same code) and [`error`]. Every dependency points
//! down this list.
//!
//! Physics: docs/model.md; equation numbers are the thesis'.
#![cfg_attr(not(test), no_std)]
#![deny(missing_docs)]
#![deny(unsafe_code)]

#[cfg(any(test, feature = "std"))]
extern crate std;

pub mod adc_status;
pub mod analysis;
pub mod capture;
pub mod capture_dma;
pub mod commission;
pub mod console;
pub mod control;
pub mod dual;
pub mod error;
pub mod hal;
pub mod health;
pub mod identify;
pub mod integrate;
pub mod model;
pub mod observe;
pub mod orbit;
pub mod real;
pub mod store;

pub use error::ParamError;
pub use real::Real;
