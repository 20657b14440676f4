//! The names the console writes for states, faults, rigs, capture states and boards, and reads
//! back ([`Token`]); and the measured regime's text.

use core::fmt;

use crate::capture::CaptureState;
use crate::control::{Fault, ModelSource, State};
use crate::model::RigId;
use crate::observe::Regime;
use crate::store::StoreState;

/// A value with a one-word name on the console.
pub trait Token: Sized + Copy + 'static {
    /// Every value.
    const ALL: &'static [Self];

    /// Its name.
    fn token(self) -> &'static str;

    /// The value of a name from [`Token::token`].
    fn from_token(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|v| v.token() == name)
    }
}

impl Token for State {
    const ALL: &'static [State] = &State::ALL;
    fn token(self) -> &'static str {
        match self {
            State::Idle => "idle",
            State::Ramp => "ramp",
            State::Dwell => "dwell",
            State::Track => "track",
            State::Stopping => "stopping",
            State::Fault => "fault",
        }
    }
}

impl Token for Fault {
    const ALL: &'static [Fault] = &Fault::ALL;
    fn token(self) -> &'static str {
        match self {
            Fault::OverForce => "over-force",
            Fault::SensorOpen => "sensor-open",
            Fault::SensorStuck => "sensor-stuck",
            Fault::AdcOverrun => "adc-overrun",
            Fault::MissedDeadline => "missed-deadline",
            Fault::BadConfig => "bad-config",
            Fault::LinkLost => "link-lost",
        }
    }
}

impl Token for RigId {
    const ALL: &'static [RigId] = &RigId::ALL;
    fn token(self) -> &'static str {
        self.name()
    }
}

/// Every model source: each preset, then the store and the console's edits.
const MODEL_SOURCES: [ModelSource; RigId::ALL.len() + 2] = {
    let mut all = [ModelSource::Stored; RigId::ALL.len() + 2];
    let mut i = 0;
    while i < RigId::ALL.len() {
        all[i] = ModelSource::Preset(RigId::ALL[i]);
        i += 1;
    }
    all[RigId::ALL.len() + 1] = ModelSource::Edited;
    all
};

impl Token for ModelSource {
    const ALL: &'static [ModelSource] = &MODEL_SOURCES;
    fn token(self) -> &'static str {
        match self {
            ModelSource::Preset(rig) => rig.name(),
            ModelSource::Stored => "stored",
            ModelSource::Edited => "edited",
        }
    }
}

impl Token for StoreState {
    const ALL: &'static [StoreState] = &StoreState::ALL;
    fn token(self) -> &'static str {
        self.name()
    }
}

impl Token for CaptureState {
    const ALL: &'static [CaptureState] =
        &[CaptureState::Off, CaptureState::Armed, CaptureState::Done];
    fn token(self) -> &'static str {
        match self {
            CaptureState::Off => "off",
            CaptureState::Armed => "armed",
            CaptureState::Done => "done",
        }
    }
}

/// A model as a log or a title names it: its source and hash (`wires 36fccdc0`,
/// `stored 5c1d2a77`).
impl fmt::Display for crate::control::ModelId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {:08x}", self.source.token(), self.hash)
    }
}

/// A fault or none: `none` or the fault's name.
pub(crate) fn write_fault(f: &mut fmt::Formatter<'_>, fault: Option<Fault>) -> fmt::Result {
    f.write_str(fault.map_or("none", Fault::token))
}

/// Reads [`write_fault`]'s text.
pub(crate) fn read_fault(s: &str) -> Option<Option<Fault>> {
    match s {
        "none" => Some(None),
        name => Fault::from_token(name).map(Some),
    }
}

/// A measured regime: `p/q`, `none`, `irregular`, or `-` (not measured yet).
pub(crate) fn write_regime(f: &mut fmt::Formatter<'_>, regime: Option<Regime>) -> fmt::Result {
    match regime {
        Some(r @ Regime::Periodic { .. }) => write!(f, "{r}"),
        Some(Regime::NoImpact) => f.write_str("none"),
        Some(Regime::Irregular) => f.write_str("irregular"),
        Some(Regime::Chaotic) => f.write_str("chaotic"),
        None => f.write_str("-"),
    }
}

/// Reads [`write_regime`]'s text.
pub(crate) fn read_regime(s: &str) -> Option<Option<Regime>> {
    match s {
        "-" => Some(None),
        "none" => Some(Some(Regime::NoImpact)),
        "irregular" => Some(Some(Regime::Irregular)),
        "chaotic" => Some(Some(Regime::Chaotic)),
        pq => match pq.parse::<Regime>() {
            Ok(r @ Regime::Periodic { p, .. }) if p > 0 => Some(Some(r)),
            _ => None,
        },
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn names_read_back<T: Token + PartialEq + fmt::Debug>() {
        for &v in T::ALL {
            assert_eq!(T::from_token(v.token()), Some(v));
        }
        assert_eq!(T::from_token("bogus"), None);
    }

    #[test]
    fn every_name_reads_back_and_names_are_distinct() {
        names_read_back::<State>();
        names_read_back::<Fault>();
        names_read_back::<RigId>();
        names_read_back::<CaptureState>();
        names_read_back::<ModelSource>();
        names_read_back::<StoreState>();
        assert_eq!(read_regime("1/1"), Some(Some(Regime::ONE_ONE)));
        assert_eq!(read_regime("none"), Some(Some(Regime::NoImpact)));
        assert_eq!(read_regime("0/1"), None);
        assert_eq!(read_fault("none"), Some(None));
        assert_eq!(read_fault("over-force"), Some(Some(Fault::OverForce)));
    }
}
