//! The replies, one line per request, as types with their text ([`fmt::Display`]) and its
//! reading ([`FromStr`]): `ok`, the status line, the help line, `id …`, `diag …`, `capture …`,
//! `segment …`, or `error: …` ([`Answer`]). Examples (docs/operator.md has them all):
//!
//! ```text
//! state=track rig=wires rig_hash=0a1b2c3d gap_mm=0.00 freq_hz=3.7000 amp_mm=0.890 regime=1/1 peak_n=95.4 peak_mg=32.64 model=ready target_hz=3.6650 band_hz=2.184..4.733 predicted_mg=32.79 force_vs_model_pct=-0.5 fault=none impacts=1042 lost_cycles=0
//! id firmware=0.1.0 board=rig rig=wires rig_hash=0a1b2c3d store=empty gap_mm=0.00 sample_rate_hz=10000 capture_rate_hz=100000 volts_per_n=0.01 offset_v=0.2 adc_full_scale_v=3.3 mass_kg=0.298 freq_window_hz=1..30 slew_hz_per_s=0.5 ramp_mm_per_s=0.5 force_limit_n=280
//! diag samples=123456 uptime_ms=12346 sample_gap_max_us=123 rx_errors=0 lines_lost=0 async_sent=41 async_dropped=0 lost_cycles=0 stack_hwm_bytes=37990 stack_size_bytes=114220 link_timeout_ms=0
//! capture state=done segments=3 samples=1200000 level_n=1.00 rate_hz=100000 segment_len=160 pre_trigger=32 max_segments=32
//! segment k=0 start=99968 n=160 codes=0f80f80f8…
//! error: only while idle: stop first
//! ```

use core::fmt;
use core::str::FromStr;

use super::board::Board;
use super::commission::CommissionView;
use super::decimal::{Decimal, Exact, parse_exact};
use super::displays_as;
use super::drop_id::IdentifyLine;
use super::fields::{Fields, WireError, decimal};
use super::link::LinkStats;
use super::request::{CommissionCommand, DraftCommand, HELP, MAX_FREQ_HZ, ParseError, Request};
use super::settings::{CalibView, ModelView, SettingsRefusal, StoreRefusal, StoreView};
use super::token::{Token, read_fault, read_regime, write_fault, write_regime};
use crate::capture::{
    CAPTURE_RATE_HZ, CaptureCommand, CaptureStatus, PRE_TRIGGER, SEGMENT_LEN, SEGMENTS, SegmentView,
};
use crate::commission::CommissionRefusal;
use crate::control::{
    Command, CommandError, Fault, MAX_FORCE_VS_MODEL_PCT, MAX_GAP_MM, ModelId, ModelStatus,
    PeakForce, Reply, SAMPLE_RATE_HZ, SensorChain, State, Status, Target,
};
use crate::hal::ADC_MAX;
use crate::store::StoreState;

/// Largest cart amplitude a line may report, mm.
const MAX_AMPLITUDE_MM: f32 = 100.0;
/// Largest force a line may report, N (far above any sensor's range).
const MAX_FORCE_N: f32 = 1e6;

/// A firmware version `major.minor.patch`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Version {
    /// Major.
    pub major: u16,
    /// Minor.
    pub minor: u16,
    /// Patch.
    pub patch: u16,
}

impl Version {
    /// The version of a `major.minor.patch[-…]` text such as `env!("CARGO_PKG_VERSION")`, at
    /// compile time (a missing or malformed part reads as 0).
    pub const fn of(text: &str) -> Version {
        let b = text.as_bytes();
        let mut parts = [0u16; 3];
        let (mut i, mut k) = (0, 0);
        while i < b.len() && k < 3 {
            let c = b[i];
            if c == b'.' {
                k += 1;
            } else if c.is_ascii_digit() {
                parts[k] = parts[k]
                    .saturating_mul(10)
                    .saturating_add((c - b'0') as u16);
            } else {
                break;
            }
            i += 1;
        }
        Version {
            major: parts[0],
            minor: parts[1],
            patch: parts[2],
        }
    }
}

impl fmt::Display for Version {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}.{}", self.major, self.minor, self.patch)
    }
}

impl FromStr for Version {
    type Err = ();
    fn from_str(s: &str) -> Result<Self, ()> {
        let mut it = s.split('.');
        let mut part = || -> Result<u16, ()> {
            let p = it.next().ok_or(())?;
            if p.is_empty() || !p.bytes().all(|b| b.is_ascii_digit()) {
                return Err(());
            }
            p.parse().map_err(|_| ())
        };
        let v = Version {
            major: part()?,
            minor: part()?,
            patch: part()?,
        };
        if it.next().is_some() {
            return Err(());
        }
        Ok(v)
    }
}

/// What the board tells about itself (`id`, `diag`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoardInfo {
    /// Firmware version.
    pub firmware: Version,
    /// Which image.
    pub board: Board,
    /// Time since start-up, ms (the board's independent time base).
    pub uptime_ms: u64,
    /// Deepest stack use so far, bytes (0 where not measured).
    pub stack_hwm_bytes: u32,
    /// The stack's size (the RAM the static data leaves), bytes (0 where not known).
    pub stack_size_bytes: u32,
    /// Longest time between two runs of the sampling task, µs (100 at 10 kHz; 0 where not
    /// measured).
    pub sample_gap_max_us: u32,
}

/// `id`: what produced a log, and the calibration the desktop converts with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdInfo {
    /// Firmware version.
    pub firmware: Version,
    /// Which image.
    pub board: Board,
    /// The active rig model: where it came from, and its hash.
    pub rig: ModelId,
    /// What the store held at start-up (or after the last `save` or `revert`).
    pub store: StoreState,
    /// Gap set now, mm.
    pub gap_mm: f32,
    /// Control sample rate, Hz.
    pub sample_rate_hz: u32,
    /// Capture sample rate, Hz.
    pub capture_rate_hz: u32,
    /// The force sensor's calibration as the controller uses it.
    pub sensor: SensorChain,
    /// Hammer mass of the rig's model, kg.
    pub mass_kg: f32,
    /// The safe window of drive frequencies, Hz.
    pub freq_window_hz: [f32; 2],
    /// The drive frequency's slew limit, Hz/s.
    pub slew_hz_per_s: f32,
    /// The amplitude ramp of a soft start or stop, mm/s.
    pub ramp_mm_per_s: f32,
    /// The force that aborts a drive, N.
    pub force_limit_n: f32,
}

impl fmt::Display for IdInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "id firmware={} board={} ",
            self.firmware,
            self.board.token(),
        )?;
        write_model_id(f, self.rig)?;
        // The calibration and limits exactly: the desktop converts and checks with them.
        write!(
            f,
            " store={} gap_mm={} sample_rate_hz={} capture_rate_hz={} volts_per_n={} offset_v={} adc_full_scale_v={} mass_kg={} freq_window_hz={}..{} slew_hz_per_s={} ramp_mm_per_s={} force_limit_n={}",
            self.store.token(),
            Decimal(self.gap_mm, 2),
            self.sample_rate_hz,
            self.capture_rate_hz,
            Exact::f32(self.sensor.volts_per_n),
            Exact::f32(self.sensor.offset_v),
            Exact::f32(self.sensor.adc_full_scale_v),
            Exact::f32(self.mass_kg),
            Exact::f32(self.freq_window_hz[0]),
            Exact::f32(self.freq_window_hz[1]),
            Exact::f32(self.slew_hz_per_s),
            Exact::f32(self.ramp_mm_per_s),
            Exact::f32(self.force_limit_n)
        )
    }
}

impl FromStr for IdInfo {
    type Err = WireError;

    /// Reads an `id` line; the calibration must pass the controller's own checks
    /// ([`SensorChain::validate`]), the rates must be this protocol's.
    fn from_str(s: &str) -> Result<Self, WireError> {
        let mut w = Fields::after(s, "id ")?;
        let id = IdInfo {
            firmware: w.with("firmware", |v| v.parse().ok())?,
            board: w.token("board")?,
            rig: read_model_id(&mut w)?,
            store: w.token("store")?,
            gap_mm: w.decimal("gap_mm", 0.0, MAX_GAP_MM)?,
            sample_rate_hz: w.int("sample_rate_hz")?,
            capture_rate_hz: w.int("capture_rate_hz")?,
            sensor: SensorChain {
                volts_per_n: exact_f32(&mut w, "volts_per_n", 0.0, f32::MAX)?,
                offset_v: exact_f32(&mut w, "offset_v", 0.0, f32::MAX)?,
                adc_full_scale_v: exact_f32(&mut w, "adc_full_scale_v", 0.0, f32::MAX)?,
            },
            mass_kg: exact_f32(&mut w, "mass_kg", 1e-6, 1e3)?,
            freq_window_hz: w.with("freq_window_hz", |v| {
                let (a, b) = v.split_once("..")?;
                let (a, b) = (parse_exact(a)? as f32, parse_exact(b)? as f32);
                ((0.0..=MAX_FREQ_HZ).contains(&a) && (a..=MAX_FREQ_HZ).contains(&b))
                    .then_some([a, b])
            })?,
            slew_hz_per_s: exact_f32(&mut w, "slew_hz_per_s", 1e-3, MAX_FREQ_HZ)?,
            ramp_mm_per_s: exact_f32(&mut w, "ramp_mm_per_s", 1e-3, MAX_AMPLITUDE_MM)?,
            force_limit_n: exact_f32(&mut w, "force_limit_n", 0.1, MAX_FORCE_N)?,
        };
        w.end()?;
        if id.sample_rate_hz != SAMPLE_RATE_HZ {
            return Err(WireError::Mismatch("sample_rate_hz"));
        }
        if id.capture_rate_hz != CAPTURE_RATE_HZ {
            return Err(WireError::Mismatch("capture_rate_hz"));
        }
        id.sensor
            .validate()
            .map_err(|e| WireError::Bad(e.field()))?;
        Ok(id)
    }
}

/// The next field `key` as an exact `f32` ([`Exact::f32`]) in `lo ..= hi`.
fn exact_f32(w: &mut Fields<'_>, key: &'static str, lo: f32, hi: f32) -> Result<f32, WireError> {
    w.with(key, |v| {
        parse_exact(v)
            .map(|x| x as f32)
            .filter(|x| (lo..=hi).contains(x))
    })
}

/// `rig=<source> rig_hash=<8 hex digits>`.
fn write_model_id(f: &mut fmt::Formatter<'_>, id: ModelId) -> fmt::Result {
    write!(f, "rig={} rig_hash={:08x}", id.source.token(), id.hash)
}

/// Reads [`write_model_id`]'s fields.
fn read_model_id(w: &mut Fields<'_>) -> Result<ModelId, WireError> {
    Ok(ModelId {
        source: w.token("rig")?,
        hash: w.with("rig_hash", |v| {
            (v.len() == 8).then(|| u32::from_str_radix(v, 16).ok())?
        })?,
    })
}

/// `diag`: the link's and the board's health.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DiagInfo {
    /// Samples the controller has processed.
    pub samples: u64,
    /// Time since start-up, ms.
    pub uptime_ms: u64,
    /// Longest time between two runs of the sampling task, µs (0 where not measured).
    pub sample_gap_max_us: u32,
    /// The link's counters.
    pub link: LinkStats,
    /// Cycles lost from `1/1` while tracking.
    pub lost_cycles: u32,
    /// Deepest stack use so far, bytes (0 where not measured).
    pub stack_hwm_bytes: u32,
    /// The stack's size, bytes (0 where not known).
    pub stack_size_bytes: u32,
    /// The link-loss watchdog's time, ms (0: off).
    pub link_timeout_ms: u32,
}

impl fmt::Display for DiagInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "diag samples={} uptime_ms={} sample_gap_max_us={} rx_errors={} lines_lost={} async_sent={} async_dropped={} lost_cycles={} stack_hwm_bytes={} stack_size_bytes={} link_timeout_ms={}",
            self.samples,
            self.uptime_ms,
            self.sample_gap_max_us,
            self.link.rx_errors,
            self.link.lines_lost,
            self.link.async_sent,
            self.link.async_dropped,
            self.lost_cycles,
            self.stack_hwm_bytes,
            self.stack_size_bytes,
            self.link_timeout_ms
        )
    }
}

impl FromStr for DiagInfo {
    type Err = WireError;
    fn from_str(s: &str) -> Result<Self, WireError> {
        let mut w = Fields::after(s, "diag ")?;
        let d = DiagInfo {
            samples: w.int("samples")?,
            uptime_ms: w.int("uptime_ms")?,
            sample_gap_max_us: w.int("sample_gap_max_us")?,
            link: LinkStats {
                rx_errors: w.int("rx_errors")?,
                lines_lost: w.int("lines_lost")?,
                async_sent: w.int("async_sent")?,
                async_dropped: w.int("async_dropped")?,
            },
            lost_cycles: w.int("lost_cycles")?,
            stack_hwm_bytes: w.int("stack_hwm_bytes")?,
            stack_size_bytes: w.int("stack_size_bytes")?,
            link_timeout_ms: w.int("link_timeout_ms")?,
        };
        w.end()?;
        Ok(d)
    }
}

impl fmt::Display for CaptureStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "capture state={} segments={} samples={} level_n={} rate_hz={} segment_len={} pre_trigger={} max_segments={}",
            self.state.token(),
            self.segments,
            self.samples,
            Decimal(self.level_n, 2),
            CAPTURE_RATE_HZ,
            SEGMENT_LEN,
            PRE_TRIGGER,
            SEGMENTS
        )
    }
}

impl FromStr for CaptureStatus {
    type Err = WireError;

    /// Reads a `capture` line; its rate, segment length, pre-trigger and capacity must be this
    /// protocol's, and the segments within the capacity.
    fn from_str(s: &str) -> Result<Self, WireError> {
        let mut w = Fields::after(s, "capture ")?;
        let c = CaptureStatus {
            state: w.token("state")?,
            segments: w.int("segments")?,
            samples: w.int("samples")?,
            level_n: w.decimal("level_n", 0.0, MAX_FORCE_N)?,
        };
        for (key, value) in [
            ("rate_hz", CAPTURE_RATE_HZ as usize),
            ("segment_len", SEGMENT_LEN),
            ("pre_trigger", PRE_TRIGGER),
            ("max_segments", SEGMENTS),
        ] {
            if w.int::<usize>(key)? != value {
                return Err(WireError::Mismatch(key));
            }
        }
        w.end()?;
        if usize::from(c.segments) > SEGMENTS {
            return Err(WireError::Mismatch("segments"));
        }
        Ok(c)
    }
}

const HEX: &[u8; 16] = b"0123456789abcdef";

impl fmt::Display for SegmentView {
    /// `segment k=<k> start=<index of the first sample at CAPTURE_RATE_HZ> n=<len> codes=<3 hex
    /// digits per 12-bit ADC code>`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "segment k={} start={} n={} codes=",
            self.k, self.start, SEGMENT_LEN
        )?;
        let mut digits = [0u8; 3];
        for &c in &self.codes {
            for (i, d) in digits.iter_mut().enumerate() {
                let nibble = (c >> (8 - 4 * i)) & 0xF;
                *d = HEX.get(usize::from(nibble)).copied().unwrap_or(b'0');
            }
            // Three ASCII hex digits are always valid UTF-8.
            f.write_str(core::str::from_utf8(&digits).unwrap_or("000"))?;
        }
        Ok(())
    }
}

impl FromStr for SegmentView {
    type Err = WireError;

    /// Reads a `segment` line: `n` must be this protocol's segment length and the codes exactly
    /// `n` 12-bit values.
    fn from_str(s: &str) -> Result<Self, WireError> {
        let mut w = Fields::after(s, "segment ")?;
        let k: u16 = w.int("k")?;
        let start = w.int("start")?;
        if w.int::<usize>("n")? != SEGMENT_LEN {
            return Err(WireError::Mismatch("n"));
        }
        let hex = w.raw("codes")?.as_bytes();
        w.end()?;
        if usize::from(k) >= SEGMENTS {
            return Err(WireError::Mismatch("k"));
        }
        if hex.len() != 3 * SEGMENT_LEN {
            return Err(WireError::Mismatch("codes"));
        }
        let mut codes = [0u16; SEGMENT_LEN];
        for (code, chunk) in codes.iter_mut().zip(hex.chunks_exact(3)) {
            for &d in chunk {
                let n = (d as char).to_digit(16).ok_or(WireError::Bad("codes"))?;
                *code = (*code << 4) | n as u16;
            }
            if *code > ADC_MAX {
                return Err(WireError::Bad("codes"));
            }
        }
        Ok(SegmentView { k, start, codes })
    }
}

impl fmt::Display for Status {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "state={} ", self.state.token(),)?;
        write_model_id(f, self.rig)?;
        write!(
            f,
            " gap_mm={} freq_hz={} amp_mm={} regime=",
            Decimal(self.gap_mm, 2),
            Decimal(self.freq_hz, 4),
            Decimal(self.amplitude_mm, 3)
        )?;
        write_regime(f, self.regime)?;
        match self.peak {
            Some(p) => write!(
                f,
                " peak_n={} peak_mg={}",
                Decimal(p.n, 1),
                Decimal(p.mg, 2)
            )?,
            None => f.write_str(" peak_n=- peak_mg=-")?,
        }
        match self.model {
            // The model's numbers exactly: what the desktop compares with its own selection.
            ModelStatus::Ready(t) => write!(
                f,
                " model=ready target_hz={} band_hz={}..{} predicted_mg={}",
                Exact::f32(t.target_hz),
                Exact::f32(t.band_hz[0]),
                Exact::f32(t.band_hz[1]),
                Exact::f32(t.impact_force_mg)
            )?,
            ModelStatus::Pending => f.write_str(" model=pending")?,
            ModelStatus::Failed => f.write_str(" model=failed")?,
        }
        if let Some(pct) = self.force_vs_model_pct {
            write!(f, " force_vs_model_pct={}", Decimal(pct, 1))?;
        }
        f.write_str(" fault=")?;
        write_fault(f, self.fault)?;
        write!(
            f,
            " impacts={} lost_cycles={}",
            self.impacts, self.lost_cycles
        )
    }
}

impl FromStr for Status {
    type Err = WireError;
    fn from_str(s: &str) -> Result<Self, WireError> {
        if !s.starts_with("state=") {
            return Err(WireError::Kind);
        }
        let mut w = Fields::new(s);
        let state = w.token("state")?;
        let rig = read_model_id(&mut w)?;
        let gap_mm = w.decimal("gap_mm", 0.0, MAX_GAP_MM)?;
        let freq_hz = w.decimal("freq_hz", 0.0, MAX_FREQ_HZ)?;
        let amplitude_mm = w.decimal("amp_mm", 0.0, MAX_AMPLITUDE_MM)?;
        let regime = w.with("regime", read_regime)?;
        let peak_n = w.opt_decimal("peak_n", 0.0, MAX_FORCE_N)?;
        let peak_mg = w.opt_decimal("peak_mg", 0.0, MAX_FORCE_N)?;
        let peak = match (peak_n, peak_mg) {
            (Some(n), Some(mg)) => Some(PeakForce { n, mg }),
            (None, None) => None,
            _ => return Err(WireError::Mismatch("peak_mg")),
        };
        let model = match w.raw("model")? {
            "ready" => ModelStatus::Ready(target(&mut w)?),
            "pending" => ModelStatus::Pending,
            "failed" => ModelStatus::Failed,
            _ => return Err(WireError::Bad("model")),
        };
        let force_vs_model_pct = match w.optional("force_vs_model_pct") {
            Some(v) => Some(decimal(
                "force_vs_model_pct",
                v,
                -MAX_FORCE_VS_MODEL_PCT,
                MAX_FORCE_VS_MODEL_PCT,
            )?),
            None => None,
        };
        let status = Status {
            state,
            rig,
            gap_mm,
            freq_hz,
            amplitude_mm,
            regime,
            peak,
            model,
            force_vs_model_pct,
            fault: w.with("fault", read_fault)?,
            impacts: w.int("impacts")?,
            lost_cycles: w.int("lost_cycles")?,
        };
        w.end()?;
        Ok(status)
    }
}

/// The `target_hz=… band_hz=…..… predicted_mg=…` fields of a ready model (exact numbers).
pub(crate) fn target(w: &mut Fields<'_>) -> Result<Target, WireError> {
    Ok(Target {
        target_hz: exact_f32(w, "target_hz", 0.0, MAX_FREQ_HZ)?,
        band_hz: exact_band(w)?,
        impact_force_mg: exact_f32(w, "predicted_mg", 0.0, MAX_FORCE_N)?,
    })
}

/// `band_hz=a..b` as two exact numbers, `0 ≤ a ≤ b ≤` [`MAX_FREQ_HZ`].
pub(crate) fn exact_band(w: &mut Fields<'_>) -> Result<[f32; 2], WireError> {
    w.with("band_hz", |v| {
        let (a, b) = v.split_once("..")?;
        let (a, b) = (parse_exact(a)? as f32, parse_exact(b)? as f32);
        ((0.0..=MAX_FREQ_HZ).contains(&a) && (a..=MAX_FREQ_HZ).contains(&b)).then_some([a, b])
    })
}

const TRIPPED: (&str, &str) = (
    "start tripped fault ",
    ": frequency or amplitude outside the limits (clear first)",
);
const NOT_IDLE: (&str, &str, &str) = (
    "only while idle: the drive is ",
    ", stop first",
    ", wait for idle",
);
const FREQ_WINDOW: (&str, &str, &str) =
    ("frequency out of the safe window: allowed ", " ..= ", " Hz");
const OUT_OF_RANGE: (&str, &str, &str) = (
    "value out of range: allowed ",
    " ..= ",
    " (0: off for link-timeout)",
);

impl fmt::Display for CommandError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CommandError::Tripped(fault) => {
                write!(f, "{}{}{}", TRIPPED.0, fault.token(), TRIPPED.1)
            }
            CommandError::NotIdle(state) => write!(
                f,
                "{}{}{}",
                NOT_IDLE.0,
                state.token(),
                if *state == State::Stopping {
                    NOT_IDLE.2
                } else {
                    NOT_IDLE.1
                }
            ),
            CommandError::FaultLatched => f.write_str("fault latched: clear first"),
            CommandError::ModelPending => {
                f.write_str("model still computing the target: wait or use freq <Hz>")
            }
            CommandError::NoTarget => {
                f.write_str("the model found no robust 1/1 target: use freq <Hz>")
            }
            CommandError::FreqOutOfWindow { min, max } => write_range(f, FREQ_WINDOW, *min, *max),
            CommandError::OutOfRange { min, max } => write_range(f, OUT_OF_RANGE, *min, *max),
        }
    }
}

/// A range's text: `(before, between, after)` around its ends, each to 2 decimals.
fn write_range(
    f: &mut fmt::Formatter<'_>,
    text: (&str, &str, &str),
    min: f32,
    max: f32,
) -> fmt::Result {
    write!(
        f,
        "{}{}{}{}{}",
        text.0,
        Decimal(min, 2),
        text.1,
        Decimal(max, 2),
        text.2
    )
}

impl FromStr for CommandError {
    type Err = ();
    fn from_str(s: &str) -> Result<Self, ()> {
        let unit = [
            CommandError::FaultLatched,
            CommandError::ModelPending,
            CommandError::NoTarget,
        ];
        if let Some(e) = unit.into_iter().find(|e| displays_as(e, s)) {
            return Ok(e);
        }
        if let Some(rest) = s.strip_prefix(NOT_IDLE.0) {
            let name = rest
                .strip_suffix(NOT_IDLE.1)
                .or_else(|| rest.strip_suffix(NOT_IDLE.2))
                .ok_or(())?;
            let e = State::from_token(name)
                .map(CommandError::NotIdle)
                .ok_or(())?;
            return if displays_as(&e, s) { Ok(e) } else { Err(()) };
        }
        if let Some(name) = s
            .strip_prefix(TRIPPED.0)
            .and_then(|r| r.strip_suffix(TRIPPED.1))
        {
            return Fault::from_token(name).map(CommandError::Tripped).ok_or(());
        }
        for (text, window) in [(FREQ_WINDOW, true), (OUT_OF_RANGE, false)] {
            let Some(range) = s.strip_prefix(text.0).and_then(|r| r.strip_suffix(text.2)) else {
                continue;
            };
            let (min, max) = range.split_once(text.1).ok_or(())?;
            let (min, max) = (
                super::parse_decimal(min).ok_or(())?,
                super::parse_decimal(max).ok_or(())?,
            );
            return Ok(if window {
                CommandError::FreqOutOfWindow { min, max }
            } else {
                CommandError::OutOfRange { min, max }
            });
        }
        Err(())
    }
}

/// Why a `capture` or `start` was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CaptureError {
    /// `capture arm` while the drive is not idle.
    NotIdle,
    /// `start` while a capture records.
    Running,
    /// `capture get k` beyond the recorded segments.
    NoSegment {
        /// Asked for.
        k: u16,
        /// Recorded.
        recorded: u16,
    },
}

const NO_SEGMENT: (&str, &str, &str) = ("segment ", " not recorded (", " recorded)");

impl fmt::Display for CaptureError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CaptureError::NotIdle => f.write_str("capture only while idle: stop first"),
            CaptureError::Running => {
                f.write_str("a capture is recording: wait for it or `capture stop`")
            }
            CaptureError::NoSegment { k, recorded } => write!(
                f,
                "{}{k}{}{recorded}{}",
                NO_SEGMENT.0, NO_SEGMENT.1, NO_SEGMENT.2
            ),
        }
    }
}

impl FromStr for CaptureError {
    type Err = ();
    fn from_str(s: &str) -> Result<Self, ()> {
        if let Some(e) = [CaptureError::NotIdle, CaptureError::Running]
            .into_iter()
            .find(|e| displays_as(e, s))
        {
            return Ok(e);
        }
        let inner = s
            .strip_prefix(NO_SEGMENT.0)
            .and_then(|r| r.strip_suffix(NO_SEGMENT.2))
            .ok_or(())?;
        let (k, recorded) = inner.split_once(NO_SEGMENT.1).ok_or(())?;
        Ok(CaptureError::NoSegment {
            k: k.parse().map_err(|_| ())?,
            recorded: recorded.parse().map_err(|_| ())?,
        })
    }
}

/// Why a line was answered with `error: …`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AnswerError {
    /// The line does not parse.
    Parse(ParseError),
    /// The controller refused the command.
    Command(CommandError),
    /// The capture refused.
    Capture(CaptureError),
    /// A receive error hit the line (or the line queue was full): it did not run.
    Lost,
    /// The line was too long or not text.
    Bad,
    /// A settings change refused.
    Settings(SettingsRefusal),
    /// A `save` or `revert` refused.
    Store(StoreRefusal),
    /// A `commission` command refused, or another command refused while commissioning.
    Commission(CommissionRefusal),
}

impl fmt::Display for AnswerError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AnswerError::Parse(e) => write!(f, "{e}"),
            AnswerError::Command(e) => write!(f, "{e}"),
            AnswerError::Capture(e) => write!(f, "{e}"),
            AnswerError::Lost => f.write_str("line lost"),
            AnswerError::Bad => f.write_str("line too long or not text"),
            AnswerError::Settings(e) => write!(f, "{e}"),
            AnswerError::Store(e) => write!(f, "{e}"),
            AnswerError::Commission(e) => write!(f, "{e}"),
        }
    }
}

impl FromStr for AnswerError {
    type Err = ();
    fn from_str(s: &str) -> Result<Self, ()> {
        if let Some(e) = [AnswerError::Lost, AnswerError::Bad]
            .into_iter()
            .find(|e| displays_as(e, s))
        {
            return Ok(e);
        }
        s.parse()
            .map(AnswerError::Command)
            .or_else(|()| s.parse().map(AnswerError::Capture))
            .or_else(|()| s.parse().map(AnswerError::Parse))
            .or_else(|()| s.parse().map(AnswerError::Settings))
            .or_else(|()| s.parse().map(AnswerError::Store))
            .or_else(|()| s.parse().map(AnswerError::Commission))
    }
}

/// The answer to one line. A segment (330 bytes) makes it large; it lives on the console
/// task's stack for one reply (no heap on the MCU to box it).
#[derive(Debug, Clone, Copy, PartialEq)]
#[allow(clippy::large_enum_variant)]
pub enum Answer {
    /// The controller's reply (`ok`, status).
    Reply(Reply),
    /// `help`.
    Help,
    /// `id`.
    Id(IdInfo),
    /// `diag`.
    Diag(DiagInfo),
    /// `capture`, `capture arm`, `capture stop`: the capture's state line.
    Capture(CaptureStatus),
    /// `capture get k`.
    Segment(SegmentView),
    /// `capture identify`.
    Identify(IdentifyLine),
    /// `model`, its edits and `draft`'s: the model line.
    Model(ModelView),
    /// `calib` and its edits: the calibration line.
    Calib(CalibView),
    /// `save` and `store`: the store line.
    Store(StoreView),
    /// `commission`, `commission start|abort`: where the sequence is.
    Commission(CommissionView),
    /// Refused (nothing changed), or a `start` that tripped a fault
    /// ([`CommandError::Tripped`]).
    Error(AnswerError),
}

const ERROR: &str = "error: ";

impl Answer {
    /// Whether this answer is of the kind `request` gets: `ok` for a command (the status line
    /// for `status`), `id …` for `id`, `diag …` for `diag`, the help line for `help`, the
    /// capture's state line for `capture`, `capture arm` and `capture stop`, segment `k` for
    /// `capture get k`; or an `error: …`, which any request may get. A reply of another kind
    /// answers another line: the desktop reports it, never prints it as this one's.
    pub fn answers(&self, request: &Request) -> bool {
        let own = match request {
            Request::Control(Command::Status) => matches!(self, Answer::Reply(Reply::Status(_))),
            Request::Control(
                Command::Stream(_)
                | Command::Rig(_)
                | Command::Gap(_)
                | Command::LinkTimeout(_)
                | Command::Tune
                | Command::Start
                | Command::Stop
                | Command::Freq(_)
                | Command::Clear,
            )
            | Request::Echo(_) => matches!(self, Answer::Reply(Reply::Ok)),
            Request::Id => matches!(self, Answer::Id(_)),
            Request::Diag => matches!(self, Answer::Diag(_)),
            Request::Help => matches!(self, Answer::Help),
            Request::Capture(CaptureCommand::Get(k)) => {
                matches!(self, Answer::Segment(s) if s.k == *k)
            }
            Request::Capture(
                CaptureCommand::Status | CaptureCommand::Stop | CaptureCommand::Arm { .. },
            ) => matches!(self, Answer::Capture(_)),
            Request::Capture(CaptureCommand::Identify) => matches!(self, Answer::Identify(_)),
            // The draft's model line, or the identification that was not adopted.
            Request::Capture(CaptureCommand::Adopt) => {
                matches!(self, Answer::Model(_) | Answer::Identify(_))
            }
            Request::Model
            | Request::EditModel(_)
            | Request::Revert
            | Request::Draft(DraftCommand::Begin | DraftCommand::Apply | DraftCommand::Discard) => {
                matches!(self, Answer::Model(_))
            }
            Request::Calib | Request::EditCalib(..) => matches!(self, Answer::Calib(_)),
            Request::Save | Request::Store => matches!(self, Answer::Store(_)),
            Request::Reset => matches!(self, Answer::Reply(Reply::Ok)),
            Request::Commission(CommissionCommand::Accept) => matches!(self, Answer::Store(_)),
            Request::Commission(_) => matches!(self, Answer::Commission(_)),
        };
        own || matches!(self, Answer::Error(_))
    }
}

impl fmt::Display for Answer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Answer::Reply(Reply::Ok) => f.write_str("ok"),
            Answer::Reply(Reply::Status(s)) => write!(f, "{s}"),
            Answer::Help => f.write_str(HELP),
            Answer::Id(i) => write!(f, "{i}"),
            Answer::Diag(d) => write!(f, "{d}"),
            Answer::Capture(c) => write!(f, "{c}"),
            Answer::Segment(s) => write!(f, "{s}"),
            Answer::Identify(l) => write!(f, "{l}"),
            Answer::Model(m) => write!(f, "{m}"),
            Answer::Calib(c) => write!(f, "{c}"),
            Answer::Store(st) => write!(f, "{st}"),
            Answer::Commission(c) => write!(f, "{c}"),
            Answer::Error(e) => write!(f, "{ERROR}{e}"),
        }
    }
}

impl FromStr for Answer {
    type Err = WireError;

    /// Reads a reply line of any kind.
    ///
    /// # Errors
    /// [`WireError::Kind`] for a line that is no reply; the kind's own error for a malformed one.
    fn from_str(s: &str) -> Result<Self, WireError> {
        if s == "ok" {
            Ok(Answer::Reply(Reply::Ok))
        } else if s == HELP {
            Ok(Answer::Help)
        } else if let Some(e) = s.strip_prefix(ERROR) {
            e.parse()
                .map(Answer::Error)
                .map_err(|()| WireError::Bad("error"))
        } else if s.starts_with("state=") {
            s.parse().map(|st| Answer::Reply(Reply::Status(st)))
        } else if s.starts_with("id ") {
            s.parse().map(Answer::Id)
        } else if s.starts_with("diag ") {
            s.parse().map(Answer::Diag)
        } else if s.starts_with("capture ") {
            s.parse().map(Answer::Capture)
        } else if s.starts_with("segment ") {
            s.parse().map(Answer::Segment)
        } else if s.starts_with("commission ") {
            s.parse().map(Answer::Commission)
        } else if s.starts_with("identify ") {
            s.parse().map(Answer::Identify)
        } else if s.starts_with("model ") {
            s.parse().map(Answer::Model)
        } else if s.starts_with("calib ") {
            s.parse().map(Answer::Calib)
        } else if s.starts_with("store ") {
            s.parse().map(Answer::Store)
        } else {
            Err(WireError::Kind)
        }
    }
}
