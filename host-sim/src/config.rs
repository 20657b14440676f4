//! Building a validated setup from the command line: rig preset → `--law` → `--config` TOML.
//!
//! The TOML file has up to three tables, each overriding only the keys it names:
//! ```toml
//! [rig]                      # shared::model::RigParams (SI units)
//! mass_kg = 0.30
//! [rig.contact.spring-dashpot]
//! damping_n_s_m = 1100.0
//! [rig.suspension.wires]     # the pendulum: length and the project's viscous damping ratio
//! length_m = 0.075           # (damping_ratio absent: 0, the thesis' undamped model)
//! damping_ratio = 0.003
//! [settings.steps]           # shared::analysis::SimSettings
//! steps_per_period = 512
//! [selection]                # shared::analysis::SelectionSpec
//! freq_margin_pct = 4.0
//! [uncertainty]              # UncertaintyTable: written by `identify contact --out`, read by `select`
//! law = "spring-dashpot"
//! coordinates = ["ln_stiffness_n_m", "ln_damping_n_s_m"]
//! mean = [15.52, 7.09]
//! covariance = [[2.7e-5, 2.8e-5], [2.8e-5, 1.5e-4]]
//! method = "parametric bootstrap: …"   # optional
//! [uncertainty.lack_of_fit]  # optional: the fit misses its data (`select` warns)
//! residual_over_noise = 21.2
//! note = "the spring-dashpot law does not fit these data: …"
//! [calibration.sensor]       # shared::control::Calibration: the rig's wiring, for
//! volts_per_n = 0.0098       # `rig model push` (the analyses do not use it)
//! [calibration.limits]
//! force_limit_n = 250.0
//! ```

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use serde::{Deserialize, Serialize};
use shared::analysis::{SelectionSpec, SimSettings, Sweep};
use shared::control::{Calibration, ControllerConfig};
use shared::error::{check_half_open, check_range};
use shared::model::{ContactLaw, ContactLawKind, RigId, RigParams};

use crate::precision::Precision;

/// Numerical profile: the analysis defaults, or the cheaper settings the firmware's model task
/// runs on the MCU (`SimSettings::embedded`, `SelectionSpec::embedded`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Default)]
pub enum Profile {
    /// Analysis defaults: N = 64, K = 16, 200-period transient, Ω/ω 0.5:5.0:0.01 for `select`.
    #[default]
    Host,
    /// The firmware's on-target model: N = 32, K = 8, 60-period transient, q ≤ 4, 8-period
    /// window, Ω/ω 1.0:3.6:0.1 for `select` (gives the firmware's target bit for bit).
    Embedded,
}

/// What a [`Setup`] is built from: the rig, the numerics and an optional TOML file (flattened
/// into the commands' arguments).
#[derive(Debug, Clone, Args)]
pub struct RigOpts {
    /// Rig: hammer on wires, or on beam springs with 170/150/135 mm couplings distance.
    #[arg(long, value_parser = rig_parser(), default_value = "wires")]
    pub rig: RigId,
    /// Contact law (default: the identified spring–dashpot of Table 3.1). Lankarani–Nikravesh
    /// is valid near e = 1 only: it rebounds at 0.663 or more whatever its e (docs/model.md).
    #[arg(long, value_parser = law_parser())]
    pub law: Option<ContactLawKind>,
    /// TOML file overriding any parameter: tables `[rig]`, `[settings]`, `[selection]` (and
    /// `[uncertainty]`, written by `identify contact --out`, for `select --uncertainty`).
    #[arg(long, value_name = "FILE.toml")]
    pub config: Option<PathBuf>,
    /// Float type of the simulation.
    #[arg(long, value_enum, default_value_t = Precision::F32)]
    pub precision: Precision,
    /// Numerical profile (defaults that `--config` then overrides).
    #[arg(long, value_enum, default_value_t = Profile::Host)]
    pub profile: Profile,
    /// Viscous damping ratio ζ of the suspension, 0 ≤ ζ < 1, over the preset's and
    /// `--config`'s: the wire pendulum's (the project's term −2ζω θ̇ added to Eq. 3-26; the
    /// `wires` preset is the thesis' undamped model, ζ = 0; a few thousandths is realistic,
    /// docs/model.md) or the beam springs' (Table 3.3: 0.004).
    #[arg(long, value_name = "ZETA")]
    pub damping_ratio: Option<f64>,
}

impl RigOpts {
    /// A rig preset as the commands see it with no other option: its identified contact law,
    /// no config file, f32, the host profile.
    #[must_use]
    pub fn preset(rig: RigId) -> Self {
        Self {
            rig,
            law: None,
            config: None,
            precision: Precision::F32,
            profile: Profile::Host,
            damping_ratio: None,
        }
    }

    /// Checks that none of a command's `outputs` (its flags and paths, `None` where not
    /// given) is the `--config` file or another output ([`crate::output::distinct_files`]).
    ///
    /// # Errors
    /// Two of them name the same file.
    pub fn check_outputs(&self, outputs: &[(&str, Option<&Path>)]) -> Result<()> {
        crate::output::distinct_files(
            &crate::output::given(&[("--config", self.config.as_deref())]),
            &crate::output::given(outputs),
        )
    }
}

/// Parses a rig preset name (`wires`, `beam-170`, …) for a command-line option.
///
/// # Errors
/// An unknown name, with the known ones.
pub fn parse_rig(s: &str) -> Result<RigId, String> {
    s.parse().map_err(|e| format!("{e}"))
}

/// Parses a contact-law name (`hertz`, `spring-dashpot`, …) for a command-line option.
///
/// # Errors
/// An unknown name, with the known ones.
pub fn parse_law(s: &str) -> Result<ContactLawKind, String> {
    s.parse().map_err(|e| format!("{e}"))
}

/// A command-line value read by a parser function (its error said as clap says a value
/// parser's) whose help lists the names it takes, from the one list the parser reads: for
/// `--law`, [`ContactLawKind::ALL`] ([`law_parser`]); for `--rig`, [`RigId::ALL`] ([`rig_parser`]).
#[derive(Clone)]
pub struct NamedValues<T> {
    parse: fn(&str) -> Result<T, String>,
    names: fn() -> Vec<&'static str>,
}

impl<T: Clone + Send + Sync + 'static> clap::builder::TypedValueParser for NamedValues<T> {
    type Value = T;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &std::ffi::OsStr,
    ) -> Result<T, clap::Error> {
        self.parse.parse_ref(cmd, arg, value)
    }

    fn possible_values(
        &self,
    ) -> Option<Box<dyn Iterator<Item = clap::builder::PossibleValue> + '_>> {
        Some(Box::new(
            (self.names)()
                .into_iter()
                .map(clap::builder::PossibleValue::new),
        ))
    }
}

/// `--law`: one of [`ContactLawKind::ALL`] by name ([`parse_law`]); the help lists them.
#[must_use]
pub fn law_parser() -> NamedValues<ContactLawKind> {
    NamedValues {
        parse: parse_law,
        names: law_names,
    }
}

/// `--rig`: one of [`RigId::ALL`] by name ([`parse_rig`]); the help lists them.
#[must_use]
pub fn rig_parser() -> NamedValues<RigId> {
    NamedValues {
        parse: parse_rig,
        names: rig_names,
    }
}

/// The names of [`RigId::ALL`], in its order.
#[must_use]
pub fn rig_names() -> Vec<&'static str> {
    RigId::NAMES.to_vec()
}

/// The names of [`ContactLawKind::ALL`], in its order.
#[must_use]
pub fn law_names() -> Vec<&'static str> {
    ContactLawKind::ALL.map(ContactLawKind::name).to_vec()
}

impl<T> NamedValues<T> {
    /// Values read by `parse`, the help listing `names()`.
    pub const fn new(
        parse: fn(&str) -> Result<T, String>,
        names: fn() -> Vec<&'static str>,
    ) -> Self {
        Self { parse, names }
    }
}

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
    /// The identified contact law's distribution, if the config file has one.
    pub uncertainty: Option<UncertaintyTable>,
    /// The rig's calibration, if the config file has a `[calibration]` table (over the
    /// firmware's defaults; checked as the board checks it).
    pub calibration: Option<Calibration>,
}

/// The `[uncertainty]` table of a config file, written by `identify contact --out` and read by
/// `select` (`--uncertainty` draws from it; a flagged fit is warned about with or without it):
/// the contact law's parameters as a normal distribution in the coordinates of
/// [`coordinate_names`] (`ln` of the scale parameters).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UncertaintyTable {
    /// The law: the same as `[rig.contact]`'s.
    pub law: ContactLawKind,
    /// Coordinate names, in the law's order ([`coordinate_names`]).
    pub coordinates: Vec<String>,
    /// Mean.
    pub mean: Vec<f64>,
    /// Covariance (symmetric, finite, positive semi-definite; `inf` on the diagonal for a
    /// coordinate the identification did not fix).
    pub covariance: Vec<Vec<f64>>,
    /// How the covariance was estimated (`select --uncertainty` says it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub method: Option<String>,
    /// Set when the identification found that the law does not fit its data (`select` warns).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lack_of_fit: Option<LackOfFit>,
}

/// The lack-of-fit verdict of an identification, as its config file carries it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LackOfFit {
    /// The error at the fit over what the sensor noise alone explains (1 when the law fits).
    pub residual_over_noise: f64,
    /// The identification's words for it.
    pub note: String,
}

/// The coordinates of the `[uncertainty]` table for `law`, in the law's parameter order: the
/// logarithm of each scale parameter (stiffness, `c_i`, `λ_i`), the others as they are (`n`, `e`).
pub fn coordinate_names(law: ContactLawKind) -> &'static [&'static str] {
    match law {
        ContactLawKind::SpringDashpot => &["ln_stiffness_n_m", "ln_damping_n_s_m"],
        ContactLawKind::Hertz => &["ln_stiffness", "exponent"],
        ContactLawKind::HuntCrossley => &["ln_stiffness", "exponent", "ln_lambda_s_m"],
        ContactLawKind::LankaraniNikravesh => &["ln_stiffness", "exponent", "restitution"],
    }
}

/// The law at coordinates `rep` of [`coordinate_names`] (e.g. a draw of `select --uncertainty`);
/// `None` if `rep` is short or the law is invalid.
pub fn law_from_coordinates(law: ContactLawKind, rep: &[f64]) -> Option<ContactLaw> {
    let get = |i: usize| rep.get(i).copied();
    let l = match law {
        ContactLawKind::SpringDashpot => ContactLaw::SpringDashpot {
            stiffness_n_m: get(0)?.exp(),
            damping_n_s_m: get(1)?.exp(),
        },
        ContactLawKind::Hertz => ContactLaw::Hertz {
            stiffness: get(0)?.exp(),
            exponent: get(1)?,
        },
        ContactLawKind::HuntCrossley => ContactLaw::HuntCrossley {
            stiffness: get(0)?.exp(),
            exponent: get(1)?,
            lambda_s_m: get(2)?.exp(),
        },
        ContactLawKind::LankaraniNikravesh => ContactLaw::LankaraniNikravesh {
            stiffness: get(0)?.exp(),
            exponent: get(1)?,
            restitution: get(2)?,
        },
    };
    l.validate().is_ok().then_some(l)
}

impl UncertaintyTable {
    /// The table as TOML (`[uncertainty]` and its `[uncertainty.lack_of_fit]`).
    ///
    /// # Errors
    /// Serialisation failure.
    pub fn to_toml(&self) -> Result<String> {
        #[derive(Serialize)]
        struct Root<'a> {
            uncertainty: &'a UncertaintyTable,
        }
        toml::to_string(&Root { uncertainty: self }).context("writing the [uncertainty] table")
    }

    /// Checks the table against the rig's contact law.
    ///
    /// # Errors
    /// The field and what is wrong with it.
    pub fn validate(&self, params: &RigParams) -> Result<()> {
        let law = params.contact.kind();
        anyhow::ensure!(
            self.law == law,
            "[uncertainty] `law` = {} but [rig.contact] is {law}",
            self.law
        );
        let expected = coordinate_names(law);
        anyhow::ensure!(
            self.coordinates
                .iter()
                .map(String::as_str)
                .eq(expected.iter().copied()),
            "[uncertainty] `coordinates` must be {expected:?} for the {law} law"
        );
        let p = expected.len();
        anyhow::ensure!(
            self.mean.len() == p && self.mean.iter().all(|v| v.is_finite()),
            "[uncertainty] `mean` must hold {p} finite numbers"
        );
        anyhow::ensure!(
            self.covariance.len() == p && self.covariance.iter().all(|r| r.len() == p),
            "[uncertainty] `covariance` must be a {p} × {p} table"
        );
        for (i, row) in self.covariance.iter().enumerate() {
            for (j, &v) in row.iter().enumerate() {
                // `inf` on the diagonal: a coordinate the identification did not fix (the
                // file still sets the law; `select --uncertainty` refuses to draw from it).
                let unbounded = i == j && v == f64::INFINITY;
                anyhow::ensure!(
                    v.is_finite() || unbounded,
                    "[uncertainty] `covariance`[{i}][{j}] = {v}: allowed finite numbers (`inf` \
                     only on the diagonal, for a coordinate the fit did not fix)"
                );
                anyhow::ensure!(
                    unbounded || (v - self.covariance[j][i]).abs() <= 1e-9 * v.abs().max(1e-300),
                    "[uncertainty] `covariance` must be symmetric"
                );
            }
            anyhow::ensure!(
                row[i] >= 0.0,
                "[uncertainty] `covariance` has a negative variance"
            );
        }
        // A covariance is positive semi-definite (up to the text's rounding); draws from
        // another matrix would be drawn from no distribution. (An `inf` variance is left to
        // `check_bounded`.)
        if self.covariance.iter().flatten().all(|v| v.is_finite()) {
            let ev = nalgebra::DMatrix::from_fn(p, p, |i, j| self.covariance[i][j])
                .symmetric_eigenvalues();
            let largest = ev.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            anyhow::ensure!(
                ev.iter().all(|&v| v >= -1e-9 * largest),
                "[uncertainty] `covariance` is not positive semi-definite (eigenvalues {}): \
                 not a covariance matrix",
                ev.iter()
                    .map(|v| format!("{v:.4e}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
        Ok(())
    }

    /// Whether every coordinate has a finite variance (draws make sense).
    ///
    /// # Errors
    /// The first unbounded coordinate.
    pub fn check_bounded(&self) -> Result<()> {
        for (i, c) in self.coordinates.iter().enumerate() {
            if !self.covariance[i][i].is_finite() {
                bail!(
                    "[uncertainty]: the identification did not fix `{c}` (unbounded interval), so \
                     draws from it would be meaningless; fit again with more data (see the \
                     file's notes)"
                );
            }
        }
        Ok(())
    }
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct ConfigFile {
    rig: Option<toml::Table>,
    settings: Option<toml::Table>,
    selection: Option<toml::Table>,
    uncertainty: Option<UncertaintyTable>,
    calibration: Option<toml::Table>,
}

impl Setup {
    /// The largest gap of this rig, mm (`RigParams::max_gap_m`: 50 mm, the wire pendulum at
    /// most `l/4`, 18.75 mm for Table 3.2's).
    pub fn max_gap_mm(&self) -> f64 {
        self.params.max_gap_m() * 1e3
    }

    /// `gap_mm` given to `flag`, checked against this rig's largest gap, in metres.
    ///
    /// # Errors
    /// NaN, negative, or beyond [`Setup::max_gap_mm`] (the flag and the range named).
    pub fn gap_m(&self, flag: &str, gap_mm: f64) -> Result<f64> {
        check_range("gap_mm", gap_mm, 0.0, self.max_gap_mm())
            .with_context(|| format!("{flag} (the {} rig's range)", self.rig))?;
        Ok(gap_mm * 1e-3)
    }

    /// The setup of a rig preset with every option at its default ([`RigOpts::preset`]).
    ///
    /// # Errors
    /// None for the built-in presets; the validation of [`Setup::from_opts`].
    pub fn preset(rig: RigId) -> Result<Self> {
        Self::from_opts(&RigOpts::preset(rig))
    }

    /// Builds and validates the setup.
    ///
    /// # Errors
    /// Unreadable or malformed TOML, unknown keys, or out-of-range values (named).
    pub fn from_opts(opts: &RigOpts) -> Result<Self> {
        let mut params = opts.rig.preset();
        if let Some(kind) = opts.law {
            params.contact = ContactLaw::preset(kind);
        }
        let mut uncertainty = None;
        let mut calibration = None;
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
            uncertainty = file.uncertainty;
            if let Some(t) = file.calibration {
                let c = merge(&Calibration::default(), t, "calibration")
                    .with_context(|| format!("{}", path.display()))?;
                c.applied_to(&ControllerConfig::default())
                    .map_err(|e| anyhow::anyhow!("calibration: {e}"))
                    .with_context(|| format!("{}", path.display()))?;
                calibration = Some(c);
            }
        }
        if let Some(zeta) = opts.damping_ratio {
            check_damping_ratio(zeta)?;
            params = params.with_damping_ratio(zeta);
        }
        params.validate().context("rig parameters")?;
        settings.bands.validate().context("settings.bands")?;
        settings.steps.validate().context("settings.steps")?;
        settings.protocol.validate().context("settings.protocol")?;
        selection.validate().context("selection")?;
        if let (Some(u), Some(path)) = (&uncertainty, &opts.config) {
            u.validate(&params)
                .with_context(|| format!("{}", path.display()))?;
        }
        Ok(Setup {
            rig: opts.rig,
            params,
            settings,
            selection,
            precision: opts.precision,
            uncertainty,
            calibration,
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
    let given = over.clone();
    overlay(&mut value, toml::Value::Table(over));
    // The error names the key's whole path: `rig.contact.hertz: missing field `stiffness``,
    // `rig.mass_kg: invalid type …`.
    serde_path_to_error::deserialize(value).map_err(|e| {
        let at = match e.path().iter().next() {
            None => table.to_string(),
            Some(_) => format!("{table}.{}", e.path()),
        };
        let message = e.inner().message();
        // An enum's table given without its variant (`[rig.contact]` with a law's fields,
        // `contact = "hertz"`, two laws at once): toml's words for it name no key.
        let shapeless = message.contains("wanted exactly 1 element")
            || message.contains("expected struct variant")
            || message.contains("unit variant");
        if let Some((at, what, names)) = enum_variants(&at).filter(|_| shapeless) {
            let mut found = toml::Value::Table(given);
            for key in at.split('.').skip(1) {
                found = found
                    .get(key)
                    .cloned()
                    .unwrap_or(toml::Value::Table(toml::Table::new()));
            }
            let found = match &found {
                toml::Value::Table(t) => t.keys().cloned().collect::<Vec<_>>().join(", "),
                other => other.to_string(),
            };
            return anyhow::anyhow!(
                "{at}: name one {what} as a table of its own, `[{at}.NAME]` with its fields, \
                 NAME one of {} (found: {found})",
                names.join(", ")
            );
        }
        anyhow::anyhow!("{at}: {message}")
    })
}

/// The config's enum table at the path `at` or one of its variants' tables: its path, what it
/// names and its variants, for the message of one given without its variant ([`merge`]).
fn enum_variants(at: &str) -> Option<(&'static str, &'static str, Vec<&'static str>)> {
    let under = |path: &str| match at.strip_prefix(path) {
        Some("") => true,
        Some(rest) => rest
            .strip_prefix('.')
            .is_some_and(|variant| !variant.contains('.')),
        None => false,
    };
    if under("rig.contact") {
        let names = ContactLawKind::ALL.iter().map(|k| k.name()).collect();
        Some(("rig.contact", "contact law", names))
    } else if under("rig.suspension") {
        Some(("rig.suspension", "suspension", vec!["wires", "beam"]))
    } else {
        None
    }
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

/// The keys of `a` that differ from `b` (recursively through tables).
fn diff(a: &toml::Value, b: &toml::Value) -> Option<toml::Value> {
    match (a, b) {
        (toml::Value::Table(ta), toml::Value::Table(tb)) => {
            let mut out = toml::Table::new();
            for (k, va) in ta {
                let d = match tb.get(k) {
                    Some(vb) => diff(va, vb),
                    None => Some(va.clone()),
                };
                if let Some(d) = d {
                    out.insert(k.clone(), d);
                }
            }
            (!out.is_empty()).then_some(toml::Value::Table(out))
        }
        _ => (a != b).then(|| a.clone()),
    }
}

/// A config file whose `[rig]` table holds `always` (keys written whatever their value, e.g.
/// `mass_kg`, `contact`) and every other key of `params` that differs from `base` (the preset
/// plus any `--config` the identification started from would be repeated, a plain preset is
/// not), with `comment` as `#` lines on top. Loaded with `--rig <same preset> --config`, it
/// reproduces `params`.
///
/// # Errors
/// Serialisation failure.
pub fn config_text(
    comment: &str,
    params: &RigParams,
    base: &RigParams,
    always: &[&str],
) -> Result<String> {
    let a = toml::Value::try_from(params).context("writing the config")?;
    let b = toml::Value::try_from(base).context("writing the config")?;
    let mut rig = match diff(&a, &b) {
        Some(toml::Value::Table(t)) => t,
        _ => toml::Table::new(),
    };
    if let toml::Value::Table(full) = &a {
        for key in always {
            if let Some(v) = full.get(*key) {
                rig.insert((*key).to_string(), v.clone());
            }
        }
    }
    let mut root = toml::Table::new();
    root.insert("rig".into(), toml::Value::Table(rig));
    let body = toml::to_string(&root).context("writing the config")?;
    let mut out = String::new();
    for line in comment.lines() {
        let _ = writeln!(out, "# {line}");
    }
    out.push_str(&body);
    Ok(out)
}

/// Checks a damping ratio given with `--damping-ratio`: finite, `0 ≤ ζ < 1`
/// ([`shared::model::MAX_DAMPING_RATIO`]: the suspension must be underdamped).
///
/// # Errors
/// NaN, infinite, negative, or 1 and above (the message names `damping_ratio` and the range).
pub fn check_damping_ratio(zeta: f64) -> Result<f64> {
    check_half_open("damping_ratio", zeta, 0.0, shared::model::MAX_DAMPING_RATIO)
        .context("--damping-ratio")
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
        assert!(e.starts_with("rig.mass: unknown field `mass`"), "{e}");
        // Every error names the key's whole path, however deep.
        for (text, expect) in [
            (
                "[contact.hertz]\nexponent = 1.5\n",
                "rig.contact.hertz: missing field `stiffness`",
            ),
            (
                "[suspension.wires]\nlen = 1.0\n",
                "rig.suspension.wires.len: unknown field `len`",
            ),
            (
                "mass_kg = \"a\"\n",
                "rig.mass_kg: invalid type: string \"a\", expected f64",
            ),
        ] {
            let t: toml::Table = toml::from_str(text).unwrap();
            let e = merge(&p, t, "rig").unwrap_err().to_string();
            assert!(e.starts_with(expect), "{text}: {e}");
        }
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
    }
}
