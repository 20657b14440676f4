//! The board's settings kept in flash ([`Store`]): the rig model, gap and calibration
//! ([`Settings`]) as a versioned record on a dedicated range of NOR flash, through
//! `sequential-storage`'s key–value map (power-fail safe and wear levelled: items are appended,
//! each with a CRC of its header and data, and a page is erased only when the other is full,
//! after copying what is still live) and `postcard` for the record's bytes.
//!
//! Two items: the record (key [`RECORD_KEY`]: version, save number, settings) and, written after
//! it, the number of the last save (key [`COUNT_KEY`]). The map skips an item whose CRC fails
//! and hands out the older value of its key, so the count is what tells a corrupt newest record
//! from an older good one: a record older than the count is reported [`StoreState::Corrupt`]. A
//! power cut between the two writes leaves a record newer than the count: the new settings,
//! whole. So the next start-up finds the old settings or the new ones, never a mix
//! (`shared/tests/all/store.rs` cuts the power at every step of a save).
//!
//! The map's operations are `async` (`embedded-storage-async`); every flash here answers at
//! once (the board's flash blocks, RAM never waits), so they are run to completion in place
//! ([`embassy_futures::block_on`]).

pub mod ram_flash;

use core::fmt;
use core::ops::Range;

use embedded_storage_async::nor_flash::{MultiwriteNorFlash, NorFlash};
use sequential_storage::cache::{Cache, Uncached};
use sequential_storage::map::{MapConfig, MapStorage};

use crate::control::{Controller, ModelSource, Settings, SettingsError};
use crate::model::EditError;

/// The store's size on the rig board, bytes: two 16 KiB flash sectors (the emulator and the
/// virtual rig keep the same geometry in RAM).
pub const STORE_BYTES: u32 = 2 * ram_flash::PAGE_BYTES as u32;

/// The record's layout version: a record of another version is not read.
pub const RECORD_VERSION: u16 = 1;
/// The record's key.
pub const RECORD_KEY: u8 = 0;
/// The save count's key.
pub const COUNT_KEY: u8 = 1;
/// The record's largest size, bytes (version, save number and settings: about 140).
pub const MAX_RECORD: usize = 240;
/// The map's work buffer: a key and the largest value, rounded up to words.
const BUFFER: usize = MAX_RECORD + 16;

/// What start-up found in the store (`id`'s `store=`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StoreState {
    /// The stored settings were read (at start-up, `revert`), or were just saved.
    Ok,
    /// Nothing stored (a new board, or a store range never written).
    Empty,
    /// The newest record is unreadable (a CRC failed, a bit flipped, bytes that do not decode).
    Corrupt,
    /// The record is of another layout version (another firmware wrote it).
    OtherVersion,
    /// The record reads but its settings fail validation (the field named in the log).
    Invalid,
    /// The flash itself failed.
    FlashError,
}

impl StoreState {
    /// Every state.
    pub const ALL: [StoreState; 6] = [
        StoreState::Ok,
        StoreState::Empty,
        StoreState::Corrupt,
        StoreState::OtherVersion,
        StoreState::Invalid,
        StoreState::FlashError,
    ];

    /// Its name (`id`'s `store=`).
    pub const fn name(self) -> &'static str {
        match self {
            StoreState::Ok => "ok",
            StoreState::Empty => "empty",
            StoreState::Corrupt => "corrupt",
            StoreState::OtherVersion => "other-version",
            StoreState::Invalid => "invalid",
            StoreState::FlashError => "flash-error",
        }
    }
}

impl fmt::Display for StoreState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// What a load found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Loaded {
    /// What the store held.
    pub state: StoreState,
    /// The settings, when [`StoreState::Ok`] (the caller validates them; a refusal is
    /// [`StoreState::Invalid`]).
    pub settings: Option<Settings>,
    /// The number of the last save (0: none).
    pub saves: u32,
}

/// Why a save failed (the store holds the last good save).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SaveError {
    /// The flash failed (or the power was cut).
    Flash,
    /// The store's map refused (corrupt beyond repair, full).
    Storage,
    /// The settings do not encode within [`MAX_RECORD`] bytes.
    TooBig,
}

/// What the store holds now (the console's `store` line).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StoreStatus {
    /// What the last load found, or [`StoreState::Ok`] after a save.
    pub state: StoreState,
    /// The number of the last save seen or made (0: none).
    pub saves: u32,
    /// The stored model's hash ([`crate::model::params_hash`]), when readable.
    pub hash: Option<u32>,
}

/// The settings store as the console service reaches it (the board's flash, the emulator's and
/// the virtual rig's RAM).
pub trait SettingsStore {
    /// What it holds now.
    fn status(&self) -> StoreStatus;
    /// Reads the stored settings.
    fn load(&mut self) -> Loaded;
    /// Stores `settings` as the next save; its number.
    ///
    /// # Errors
    /// [`SaveError`]: the store keeps its last good save.
    fn save(&mut self, settings: &Settings) -> Result<u32, SaveError>;
    /// The stored settings read but were refused by the controller: the state becomes
    /// [`StoreState::Invalid`].
    fn note_invalid(&mut self);
}

/// The settings store over a NOR flash `F`.
pub struct Store<F: NorFlash> {
    map: MapStorage<u8, F, Cache<Uncached, Uncached, Uncached, u8>>,
    /// The number of the last save seen or made.
    saves: u32,
    status: StoreStatus,
}

/// Why a store could not be made.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BadRange;

impl<F: NorFlash + MultiwriteNorFlash> Store<F> {
    /// A store on `range` of `flash` (at least two erase pages, on page boundaries).
    ///
    /// # Errors
    /// [`BadRange`]: the range is not whole pages, or fewer than two.
    pub fn new(flash: F, range: Range<u32>) -> Result<Self, BadRange> {
        let config = MapConfig::try_new(range).map_err(|_| BadRange)?;
        Ok(Store {
            map: MapStorage::new(flash, config, Cache::new_uncached()),
            saves: 0,
            status: StoreStatus {
                state: StoreState::Empty,
                saves: 0,
                hash: None,
            },
        })
    }

    /// The flash back (the store dropped).
    pub fn into_flash(self) -> F {
        self.map.destroy().0
    }

    /// Reads the stored settings: what [`Loaded`] says.
    pub fn load(&mut self) -> Loaded {
        let mut buf = [0u8; BUFFER];
        let count = embassy_futures::block_on(self.map.fetch_item::<&[u8]>(&mut buf, &COUNT_KEY));
        let count = match count {
            Ok(Some(bytes)) => read_u32(bytes),
            Ok(None) => Some(0),
            Err(_) => None,
        };
        let mut buf = [0u8; BUFFER];
        let record = embassy_futures::block_on(self.map.fetch_item::<&[u8]>(&mut buf, &RECORD_KEY));
        let (state, settings, saves) = match (count, record) {
            (None, _) | (_, Err(sequential_storage::Error::Corrupted { .. })) => {
                (StoreState::Corrupt, None, 0)
            }
            (_, Err(sequential_storage::Error::Storage { .. })) => {
                (StoreState::FlashError, None, 0)
            }
            (_, Err(_)) => (StoreState::Corrupt, None, 0),
            (Some(0), Ok(None)) => (StoreState::Empty, None, 0),
            // A count but no record: the record's only copy is unreadable.
            (Some(n), Ok(None)) => (StoreState::Corrupt, None, n),
            (Some(n), Ok(Some(bytes))) => match decode(bytes) {
                Err(state) => (state, None, n),
                // Older than the count: the newest record was skipped as corrupt.
                Ok((save, _)) if save < n => (StoreState::Corrupt, None, n),
                Ok((save, s)) => (StoreState::Ok, Some(s), save),
            },
        };
        self.saves = self.saves.max(saves);
        self.status = StoreStatus {
            state,
            saves,
            hash: settings.map(|s| crate::model::params_hash(&s.params)),
        };
        Loaded {
            state,
            settings,
            saves,
        }
    }

    /// Stores `settings` as the next save; its number.
    ///
    /// # Errors
    /// [`SaveError`]; the store then holds the last good save (or, after a power cut, the one
    /// that was being written, whole).
    pub fn save(&mut self, settings: &Settings) -> Result<u32, SaveError> {
        // Numbered after the last save the store holds, whether or not it was loaded.
        let mut buf = [0u8; BUFFER];
        let stored = embassy_futures::block_on(self.map.fetch_item::<&[u8]>(&mut buf, &COUNT_KEY))
            .ok()
            .flatten()
            .and_then(read_u32)
            .unwrap_or(0);
        let n = self.saves.max(stored).wrapping_add(1).max(1);
        let mut record = [0u8; MAX_RECORD];
        let len = encode(n, settings, &mut record)?;
        let mut buf = [0u8; BUFFER];
        embassy_futures::block_on(self.map.store_item(&mut buf, &RECORD_KEY, &&record[..len]))
            .map_err(save_error)?;
        let count = n.to_le_bytes();
        embassy_futures::block_on(self.map.store_item(&mut buf, &COUNT_KEY, &&count[..]))
            .map_err(save_error)?;
        self.saves = n;
        self.status = StoreStatus {
            state: StoreState::Ok,
            saves: n,
            hash: Some(crate::model::params_hash(&settings.params)),
        };
        Ok(n)
    }
}

impl<F: NorFlash + MultiwriteNorFlash> SettingsStore for Store<F> {
    fn status(&self) -> StoreStatus {
        self.status
    }
    fn load(&mut self) -> Loaded {
        Store::load(self)
    }
    fn save(&mut self, settings: &Settings) -> Result<u32, SaveError> {
        Store::save(self, settings)
    }
    fn note_invalid(&mut self) {
        self.status.state = StoreState::Invalid;
    }
}

/// What start-up made of the store ([`start_up`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StartUp {
    /// The stored settings run: this save's.
    Stored {
        /// The save's number.
        save: u32,
    },
    /// The controller's preset runs: the store held nothing usable.
    Fallback {
        /// What the store held ([`StoreState::Invalid`]: settings the controller refused).
        state: StoreState,
        /// The number of the last save seen.
        saves: u32,
        /// The field the controller refused, for [`StoreState::Invalid`].
        field: Option<&'static str>,
    },
}

/// Start-up: the stored settings into `controller` (made with the fallback preset, gap and
/// configuration), or, when the store holds none it can use, the controller left as it is and
/// the reason. The firmware and the virtual rig start the same way.
pub fn start_up(store: &mut dyn SettingsStore, controller: &mut Controller) -> StartUp {
    let loaded = store.load();
    let Some(settings) = loaded.settings else {
        return StartUp::Fallback {
            state: loaded.state,
            saves: loaded.saves,
            field: None,
        };
    };
    match controller.load_settings(&settings, ModelSource::Stored) {
        Ok(()) => StartUp::Stored { save: loaded.saves },
        Err(e) => {
            store.note_invalid();
            StartUp::Fallback {
                state: StoreState::Invalid,
                saves: loaded.saves,
                field: match e {
                    SettingsError::Calibration(p) | SettingsError::Invalid(p) => Some(p.field()),
                    SettingsError::Model(EditError::Invalid(p)) => Some(p.field()),
                    SettingsError::Model(EditError::NotOfThisModel { field, .. }) => {
                        Some(field.name())
                    }
                    SettingsError::Command(_) | SettingsError::NoDraft => None,
                },
            }
        }
    }
}

fn save_error<E>(e: sequential_storage::Error<E>) -> SaveError {
    match e {
        sequential_storage::Error::Storage { .. } => SaveError::Flash,
        sequential_storage::Error::ItemTooBig => SaveError::TooBig,
        _ => SaveError::Storage,
    }
}

fn read_u32(bytes: &[u8]) -> Option<u32> {
    Some(u32::from_le_bytes(bytes.try_into().ok()?))
}

/// The record's bytes: version (2, little-endian), save number (4), the settings (postcard).
fn encode(save: u32, s: &Settings, out: &mut [u8; MAX_RECORD]) -> Result<usize, SaveError> {
    out[..2].copy_from_slice(&RECORD_VERSION.to_le_bytes());
    out[2..6].copy_from_slice(&save.to_le_bytes());
    let n = postcard::to_slice(s, &mut out[6..])
        .map_err(|_| SaveError::TooBig)?
        .len();
    Ok(6 + n)
}

/// The save number and settings of a record, or what is wrong with it.
fn decode(bytes: &[u8]) -> Result<(u32, Settings), StoreState> {
    let version = bytes
        .get(..2)
        .and_then(|b| b.try_into().ok())
        .map(u16::from_le_bytes)
        .ok_or(StoreState::Corrupt)?;
    if version != RECORD_VERSION {
        return Err(StoreState::OtherVersion);
    }
    let save = bytes
        .get(2..6)
        .and_then(read_u32)
        .ok_or(StoreState::Corrupt)?;
    let (settings, rest) =
        postcard::take_from_bytes::<Settings>(&bytes[6..]).map_err(|_| StoreState::Corrupt)?;
    if !rest.is_empty() {
        return Err(StoreState::Corrupt);
    }
    Ok((save, settings))
}
