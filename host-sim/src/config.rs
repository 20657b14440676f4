//! Building a validated setup from the command line: rig preset → `--law` → `--config` TOML.
//!
//! The TOML file has up to three tables, each overriding only the keys it names:
//! ```toml
//! [rig]                      # shared::model::RigParams (SI units)
//! mass_kg = 0.30
//! [rig.contact.spring-dashpot]
//! damping_n_s_m = 1100.0
//! [settings.steps]           # shared::analysis::SimSettings
//! steps_per_period = 512
//! [selection]                # shared::analysis::SelectionSpec
//! freq_margin_pct = 4.0
//! ```

use std::path::Path;

use anyhow::{Context, Result, bail};
use serde::Deserialize;
use shared::analysis::{SelectionSpec, SimSettings, Sweep};
use shared::error::check_range;
use shared::model::{ContactLaw, RigId, RigParams};

use crate::cli::{Precision, Profile, RigOpts};

/// Largest gap accepted on the command line, mm.
pub const MAX_GAP_MM: f64 = 50.0;

/// A validated rig and numerical setup.
#[derive(Debug, Clone)]
pub struct Setup {
    /// Which preset it started from.
    pub rig: RigId,
    /// Parameters after `--law` and `--config`.
    pub params: RigParams,
    /// Numerical settings.
    pub settings: SimSettings,
    /// Selection spec (only `select` uses it).
    pub selection: SelectionSpec,
    /// Float type.
    pub precision: Precision,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct ConfigFile {
    rig: Option<toml::Table>,
    settings: Option<toml::Table>,
    selection: Option<toml::Table>,
}

impl Setup {
    /// Builds and validates the setup.
    ///
    /// # Errors
    /// Unreadable or malformed TOML, unknown keys, or out-of-range values (named).
    pub fn from_opts(opts: &RigOpts) -> Result<Self> {
        let mut params = opts.rig.preset();
        if let Some(kind) = opts.law {
            params.contact = ContactLaw::preset(kind);
        }
        let (mut settings, mut selection) = match opts.profile {
            Profile::Host => (SimSettings::default(), SelectionSpec::default()),
            Profile::Embedded => (SimSettings::embedded(), SelectionSpec::embedded()),
        };
        if let Some(path) = &opts.config {
            let file = read_config(path)?;
            if let Some(t) = file.rig {
                params = merge(&params, t, "rig").with_context(|| format!("{}", path.display()))?;
            }
            if let Some(t) = file.settings {
                settings = merge(&settings, t, "settings")
                    .with_context(|| format!("{}", path.display()))?;
            }
            if let Some(t) = file.selection {
                selection = merge(&selection, t, "selection")
                    .with_context(|| format!("{}", path.display()))?;
            }
        }
        params.validate().context("rig parameters")?;
        settings.bands.validate().context("settings.bands")?;
        settings.steps.validate().context("settings.steps")?;
        settings.protocol.validate().context("settings.protocol")?;
        selection.validate().context("selection")?;
        Ok(Setup {
            rig: opts.rig,
            params,
            settings,
            selection,
            precision: opts.precision,
        })
    }
}

fn read_config(path: &Path) -> Result<ConfigFile> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read --config {}", path.display()))?;
    toml::from_str(&text).with_context(|| format!("malformed --config {}", path.display()))
}

/// Overlays `over` on the serialised `base` and deserialises the result (unknown keys rejected).
/// An enum given under a different variant (e.g. `[rig.contact.hertz]` over a spring–dashpot
/// base) replaces the base value instead of merging with it.
fn merge<T: serde::Serialize + serde::de::DeserializeOwned>(
    base: &T,
    over: toml::Table,
    table: &str,
) -> Result<T> {
    let mut value = toml::Value::try_from(base).context("internal: serialising defaults")?;
    overlay(&mut value, toml::Value::Table(over));
    value
        .try_into()
        .map_err(|e: toml::de::Error| anyhow::anyhow!("[{table}]: {}", e.message()))
}

fn overlay(base: &mut toml::Value, over: toml::Value) {
    match (base, over) {
        (toml::Value::Table(b), toml::Value::Table(o)) => {
            // A single-key table over a single-key table with another key: an enum variant switch.
            let variant_switch = b.len() == 1
                && o.len() == 1
                && b.keys().next() != o.keys().next()
                && b.values().all(toml::Value::is_table)
                && o.values().all(toml::Value::is_table);
            if variant_switch {
                *b = o;
                return;
            }
            for (k, v) in o {
                match b.get_mut(&k) {
                    Some(slot) => overlay(slot, v),
                    None => {
                        b.insert(k, v);
                    }
                }
            }
        }
        (b, o) => *b = o,
    }
}

/// Checks a gap given in mm on the command line and returns it in m.
///
/// # Errors
/// NaN, negative or larger than [`MAX_GAP_MM`].
pub fn gap_m_from_mm(flag: &str, gap_mm: f64) -> Result<f64> {
    check_range("gap_mm", gap_mm, 0.0, MAX_GAP_MM).with_context(|| flag.to_string())?;
    Ok(gap_mm * 1e-3)
}

/// Parses a sweep `A:B:STEP` given to `flag`.
///
/// # Errors
/// Not three numbers, NaN, `A > B`, `STEP ≤ 0`, too many points, or values outside
/// `[min, max]`.
pub fn parse_sweep(flag: &'static str, text: &str, min: f64, max: f64) -> Result<Sweep> {
    let parts: Vec<&str> = text.split(':').collect();
    if parts.len() != 3 {
        bail!("{flag} {text}: expected START:END:STEP, e.g. 0.5:5.0:0.02");
    }
    let mut v = [0.0; 3];
    for (slot, p) in v.iter_mut().zip(&parts) {
        *slot = p
            .trim()
            .parse::<f64>()
            .with_context(|| format!("{flag} {text}: `{p}` is not a number"))?;
    }
    let sweep = Sweep::new(flag, v[0], v[1], v[2]).with_context(|| format!("{flag} {text}"))?;
    for x in [v[0], v[1]] {
        check_range(flag, x, min, max).with_context(|| format!("{flag} {text}"))?;
    }
    Ok(sweep)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_overrides_merge_and_switch_law() {
        let p = RigId::Wires.preset();
        let t: toml::Table =
            toml::from_str("mass_kg = 0.5\n[contact.hertz]\nstiffness = 1e9\nexponent = 1.5\n")
                .unwrap();
        let q: RigParams = merge(&p, t, "rig").unwrap();
        assert_eq!(q.mass_kg, 0.5);
        assert_eq!(q.amplitude_m, p.amplitude_m);
        assert_eq!(
            q.contact,
            ContactLaw::Hertz {
                stiffness: 1e9,
                exponent: 1.5
            }
        );
        let bad: toml::Table = toml::from_str("mass = 0.5").unwrap();
        let e = merge(&p, bad, "rig").unwrap_err().to_string();
        assert!(e.contains("mass"), "{e}");
    }

    #[test]
    fn sweeps_are_checked() {
        assert_eq!(
            parse_sweep("--omega-ratio", "0.5:5.0:0.02", 0.05, 50.0)
                .unwrap()
                .len(),
            226
        );
        for bad in [
            "5:0.5:0.1",
            "0.5:5",
            "a:1:0.1",
            "0.5:5:0",
            "0.5:5:-1",
            "NaN:1:0.1",
            "0.01:1:0.1",
        ] {
            assert!(
                parse_sweep("--omega-ratio", bad, 0.05, 50.0).is_err(),
                "{bad}"
            );
        }
        assert!(gap_m_from_mm("--gap-mm", -0.1).is_err());
        assert!(gap_m_from_mm("--gap-mm", f64::NAN).is_err());
    }
}
