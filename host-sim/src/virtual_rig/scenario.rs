//! A virtual-rig scenario (`hil --scenario FILE.toml`): the plant's chains and settings, the
//! controller's configuration, timed console commands and injected faults.
//!
//! ```toml
//! model_delay_s = 0.5            # the MCU's model computation time (the result arrives then)
//! [plant]                        # rk4 steps per sample, refinement, bands
//! steps_per_sample = 10
//! contact_stiffness_factor = 1.0 # the real contact harder/softer than the model's
//! contact_damping_factor = 1.0   # spring–dashpot c_i over the model's (after the above)
//! natural_freq_factor = 1.0      # the suspension's ω over the model's
//! damping_ratio = 0.01           # the suspension's ζ (absent: the model's)
//! [plant.contact.hunt-crossley]  # the plant's own contact law (absent: the model's, scaled)
//! stiffness = 2.1e9
//! exponent = 1.6
//! lambda_s_m = 0.6
//! [drive]                        # amp_tau_s, cart_mm_per_v, dac_full_scale_v
//! [sensor]                       # volts_per_n, offset_v, noise_v, adc_full_scale_v, seed
//! [controller]                   # shared::control::ControllerConfig (the firmware's defaults)
//! [[commands]]                   # console lines (default: `start` at 1.0 s)
//! at_s = 1.0
//! line = "start"
//! [[faults]]
//! at_s = 20.0
//! kind = "sensor-open"           # sensor-open | sensor-stuck-high | sensor-stuck-low | sensor-ok
//!                                # | gain (factor) | drift (duration_s, natural_freq_pct,
//!                                #   contact_stiffness_pct)
//! [[drops]]                      # a drop test: the idle hammer released at rest
//! at_s = 2.0
//! release_mm = 3.0               # from the impact surface (> the rig's gap)
//! ```

use std::path::Path;

use anyhow::{Context, Result, bail, ensure};
use serde::{Deserialize, Serialize};
use shared::control::ControllerConfig;

use super::chains::SensorChainSim;
use super::plant::{DriveChainSim, PlantSettings};

/// The plant section: integration settings and how the real rig differs from the model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PlantSection {
    /// RK4 steps per sample (10).
    pub steps_per_sample: u32,
    /// Steps a region-changing step is split into (16).
    pub refine: u32,
    /// The plant's contact stiffness (and damping) over the preset's (1.0).
    pub contact_stiffness_factor: f64,
    /// The plant's spring–dashpot damping `c_i` over the preset's after the stiffness factor
    /// (1.0).
    pub contact_damping_factor: f64,
    /// The plant's natural frequency over the preset's (1.0; the pendulum's length by its
    /// square).
    pub natural_freq_factor: f64,
    /// The plant's suspension damping ratio (absent: the preset's).
    pub damping_ratio: Option<f64>,
    /// The plant's own contact law (absent: the preset's with the factors above).
    pub contact: Option<shared::model::ContactLaw>,
}

impl Default for PlantSection {
    fn default() -> Self {
        let d = PlantSettings::default();
        PlantSection {
            steps_per_sample: d.steps_per_sample,
            refine: d.refine,
            contact_stiffness_factor: 1.0,
            contact_damping_factor: 1.0,
            natural_freq_factor: 1.0,
            damping_ratio: None,
            contact: None,
        }
    }
}

impl PlantSection {
    /// The plant's rig: `preset` changed by this section.
    ///
    /// # Errors
    /// Parameters outside the model's ranges, named.
    pub fn params(&self, preset: &shared::model::RigParams) -> Result<shared::model::RigParams> {
        use shared::model::ContactLaw;
        let mut p = preset.with_contact_scaled(self.contact_stiffness_factor);
        if let ContactLaw::SpringDashpot { damping_n_s_m, .. } = &mut p.contact {
            *damping_n_s_m *= self.contact_damping_factor;
        }
        if let Some(law) = self.contact {
            p.contact = law;
        }
        let mut p = p.with_natural_freq_scaled(self.natural_freq_factor);
        if let Some(zeta) = self.damping_ratio {
            p = p.with_damping_ratio(zeta);
        }
        p.validate()
            .map_err(|e| anyhow::anyhow!("[plant]: the plant's rig: {e}"))?;
        Ok(p)
    }

    /// The integration settings.
    pub fn settings(&self) -> PlantSettings {
        PlantSettings {
            steps_per_sample: self.steps_per_sample,
            refine: self.refine,
            ..PlantSettings::default()
        }
    }
}

/// A console line sent at a given rig time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimedCommand {
    /// Rig time, s.
    pub at_s: f64,
    /// The line (without line ending).
    pub line: String,
}

/// A fault injected at rig time `at_s` (s).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum TimedFault {
    /// The sensor signal drops to the offset.
    SensorOpen {
        /// Rig time, s.
        at_s: f64,
    },
    /// The ADC pinned at 4095.
    SensorStuckHigh {
        /// Rig time, s.
        at_s: f64,
    },
    /// The ADC pinned at 0.
    SensorStuckLow {
        /// Rig time, s.
        at_s: f64,
    },
    /// The sensor works again.
    SensorOk {
        /// Rig time, s.
        at_s: f64,
    },
    /// The sensor gain is multiplied by `factor`.
    Gain {
        /// Rig time, s.
        at_s: f64,
        /// Gain multiplier.
        factor: f64,
    },
    /// The rig drifts linearly over `duration_s`: natural frequency and/or contact stiffness
    /// change by the given percentages.
    Drift {
        /// Rig time, s.
        at_s: f64,
        /// Duration, s.
        duration_s: f64,
        /// Natural frequency change, % (wires: through the pendulum length).
        #[serde(default)]
        natural_freq_pct: f64,
        /// Contact stiffness change, %.
        #[serde(default)]
        contact_stiffness_pct: f64,
    },
}

impl TimedFault {
    /// When it happens, s.
    pub fn at_s(&self) -> f64 {
        match *self {
            TimedFault::SensorOpen { at_s }
            | TimedFault::SensorStuckHigh { at_s }
            | TimedFault::SensorStuckLow { at_s }
            | TimedFault::SensorOk { at_s }
            | TimedFault::Gain { at_s, .. }
            | TimedFault::Drift { at_s, .. } => at_s,
        }
    }
}

/// A drop test: at `at_s` the hammer is released at rest `release_mm` from the impact surface
/// (thesis §3.3.2; meant for an idle drive, e.g. with `capture arm` before it).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimedDrop {
    /// Rig time, s.
    pub at_s: f64,
    /// Distance from the impact surface, mm.
    pub release_mm: f64,
}

/// A whole scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Scenario {
    /// Rig time the model's result takes to arrive, s (0.5: the MCU's budget).
    pub model_delay_s: f64,
    /// The plant.
    pub plant: PlantSection,
    /// Drive chain.
    pub drive: DriveChainSim,
    /// Sensing chain.
    pub sensor: SensorChainSim,
    /// The controller's configuration (the firmware's defaults).
    pub controller: ControllerConfig,
    /// Console commands (default: `start` at 1.0 s).
    pub commands: Vec<TimedCommand>,
    /// Injected faults.
    pub faults: Vec<TimedFault>,
    /// Drop tests.
    pub drops: Vec<TimedDrop>,
    /// The operator's drops when the board's commissioning asks for one; default: one, from
    /// the height the prompt gives, 0.5 s after it. Empty: the operator never drops.
    pub prompted_drops: Vec<PromptedDrop>,
}

/// A drop the operator makes when the commissioning prompts one.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PromptedDrop {
    /// Time after the prompt, s.
    pub after_s: f64,
    /// Distance from the impact surface, mm (absent: the prompt's).
    #[serde(default)]
    pub release_mm: Option<f64>,
}

impl Default for Scenario {
    fn default() -> Self {
        Scenario {
            model_delay_s: 0.5,
            plant: PlantSection::default(),
            drive: DriveChainSim::default(),
            sensor: SensorChainSim::default(),
            controller: ControllerConfig::default(),
            commands: vec![TimedCommand {
                at_s: 1.0,
                line: "start".into(),
            }],
            faults: Vec::new(),
            drops: Vec::new(),
            prompted_drops: vec![PromptedDrop {
                after_s: 0.5,
                release_mm: None,
            }],
        }
    }
}

impl Scenario {
    /// Reads and validates a scenario file.
    ///
    /// # Errors
    /// Unreadable or malformed TOML, unknown keys, out-of-range values (named).
    pub fn from_file(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read --scenario {}", path.display()))?;
        let s: Scenario = toml::from_str(&text)
            .with_context(|| format!("malformed --scenario {}", path.display()))?;
        s.validate()
            .with_context(|| format!("--scenario {}", path.display()))?;
        Ok(s)
    }

    /// Checks the values.
    ///
    /// # Errors
    /// The first bad field, named with its allowed range.
    pub fn validate(&self) -> Result<()> {
        let finite_in = |name: &str, v: f64, lo: f64, hi: f64| -> Result<()> {
            if !v.is_finite() || v < lo || v > hi {
                bail!("`{name}` = {v} is out of range: allowed {lo} ..= {hi}");
            }
            Ok(())
        };
        finite_in("model_delay_s", self.model_delay_s, 0.0, 60.0)?;
        finite_in(
            "plant.contact_stiffness_factor",
            self.plant.contact_stiffness_factor,
            0.01,
            100.0,
        )?;
        finite_in(
            "plant.contact_damping_factor",
            self.plant.contact_damping_factor,
            0.01,
            100.0,
        )?;
        finite_in(
            "plant.natural_freq_factor",
            self.plant.natural_freq_factor,
            0.5,
            2.0,
        )?;
        if let Some(z) = self.plant.damping_ratio {
            finite_in("plant.damping_ratio", z, 0.0, 0.99)?;
        }
        self.controller.validate().context("[controller]")?;
        for c in &self.commands {
            finite_in("commands.at_s", c.at_s, 0.0, 1e6)?;
            ensure!(
                !c.line.bytes().any(shared::console::is_line_end),
                "`commands.line` = \"{}\" holds a line break: one console line a [[commands]] \
                 entry (the rig would read two requests)",
                c.line.escape_debug()
            );
        }
        for d in &self.drops {
            finite_in("drops.at_s", d.at_s, 0.0, 1e6)?;
            finite_in("drops.release_mm", d.release_mm, 0.001, 20.0)?;
        }
        for d in &self.prompted_drops {
            finite_in("prompted_drops.after_s", d.after_s, 0.0, 1e6)?;
            if let Some(h) = d.release_mm {
                finite_in("prompted_drops.release_mm", h, 0.001, 50.0)?;
            }
        }
        for f in &self.faults {
            finite_in("faults.at_s", f.at_s(), 0.0, 1e6)?;
            match *f {
                TimedFault::Gain { factor, .. } => finite_in("faults.factor", factor, 0.0, 100.0)?,
                TimedFault::Drift {
                    duration_s,
                    natural_freq_pct,
                    contact_stiffness_pct,
                    ..
                } => {
                    finite_in("faults.duration_s", duration_s, 0.0, 1e6)?;
                    finite_in("faults.natural_freq_pct", natural_freq_pct, -50.0, 100.0)?;
                    finite_in(
                        "faults.contact_stiffness_pct",
                        contact_stiffness_pct,
                        -90.0,
                        1000.0,
                    )?;
                }
                _ => {}
            }
        }
        Ok(())
    }
}
