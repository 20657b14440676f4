//! The settings store against a NOR flash in RAM with the rig board's geometry: what a save
//! keeps and a later start-up reads, through power cuts at every step of a save (every word
//! written, every kilobyte erased), flipped bits, another layout version, and hundreds of saves
//! (the pages' rotation).

use embassy_futures::block_on;
use sequential_storage::cache::Cache;
use sequential_storage::map::{MapConfig, MapStorage};
use shared::control::{CalibField, Calibration, Settings};
use shared::model::{ContactLawKind, ModelEdit, ModelField, RigId, params_hash};
use shared::store::ram_flash::{PAGE_BYTES, RamFlash};
use shared::store::{COUNT_KEY, RECORD_KEY, SaveError, SettingsStore, Store, StoreState};

const BYTES: usize = 2 * PAGE_BYTES;

fn store(mem: &mut [u8]) -> Store<RamFlash<&mut [u8]>> {
    Store::new(RamFlash::new(mem), 0..BYTES as u32).unwrap()
}

/// Settings number `k`: a distinct model (its mass) and calibration (its gain) for each `k`.
fn settings(k: u32) -> Settings {
    let params = RigId::Wires
        .preset()
        .edited(ModelEdit::Law(ContactLawKind::HuntCrossley))
        .unwrap()
        .edited(ModelEdit::Set(
            ModelField::MassKg,
            0.2 + f64::from(k) * 1e-4,
        ))
        .unwrap();
    Settings {
        params,
        gap_mm: (k % 10) as f32 * 0.1,
        calibration: Calibration::default().with(CalibField::VoltsPerN, 0.01 + k as f32 * 1e-6),
    }
}

#[test]
fn a_save_is_read_back_at_the_next_start_up() {
    let mut mem = vec![0xffu8; BYTES];
    let loaded = store(&mut mem).load();
    assert_eq!(
        (loaded.state, loaded.settings, loaded.saves),
        (StoreState::Empty, None, 0)
    );
    let mut s = store(&mut mem);
    assert_eq!(s.save(&settings(1)), Ok(1));
    assert_eq!(s.save(&settings(2)), Ok(2));
    let loaded = store(&mut mem).load();
    assert_eq!(loaded.state, StoreState::Ok);
    assert_eq!(loaded.settings, Some(settings(2)));
    assert_eq!(loaded.saves, 2);
}

#[test]
fn hundreds_of_saves_rotate_the_pages_and_each_reads_back() {
    let mut mem = vec![0xffu8; BYTES];
    let mut s = store(&mut mem);
    for k in 1..=400 {
        assert_eq!(s.save(&settings(k)), Ok(k), "save {k}");
        let flash = s.into_flash();
        s = Store::new(flash, 0..BYTES as u32).unwrap();
        let loaded = s.load();
        assert_eq!(loaded.settings, Some(settings(k)), "save {k}");
    }
    // 400 saves of about 160 bytes (the record and the count, with their headers) fill a
    // 16 KiB page every hundred or so: the pages were erased in turn.
    let erased = s.into_flash().pages_erased();
    assert!((3..=5).contains(&erased), "{erased} page erases");
}

/// Saves `n` settings on a fresh flash; whether each erased a page.
fn prefilled(mem: &mut [u8], n: u32) -> Vec<bool> {
    mem.fill(0xff);
    let mut s = store(mem);
    let mut erased = Vec::new();
    let mut before = 0;
    for k in 1..=n {
        s.save(&settings(k)).unwrap();
        let flash = s.into_flash();
        erased.push(flash.pages_erased() > before);
        before = flash.pages_erased();
        s = Store::new(flash, 0..BYTES as u32).unwrap();
    }
    erased
}

#[test]
fn a_power_cut_at_any_step_of_a_save_leaves_the_old_settings_or_the_new_whole() {
    let mut mem = vec![0xffu8; BYTES];
    // The save that erases a page (the riskiest: live items are copied first) and an ordinary
    // one.
    let erased = prefilled(&mut mem, 200);
    let erasing = erased.iter().position(|&e| e).expect("a save that erases") as u32;
    assert!(erasing > 10, "save {} erased", erasing + 1);
    for before in [3, erasing] {
        let old = settings(before);
        let new = settings(before + 1);
        // The steps of that save done whole.
        prefilled(&mut mem, before);
        let mut s = store(&mut mem);
        s.load();
        let total = {
            let base = {
                let f = s.into_flash();
                f.steps()
            };
            let mut s = store(&mut mem);
            s.load();
            s.save(&new).unwrap();
            s.into_flash().steps() - base
        };
        // About 40 words; the save that erases, a page of 16 steps more and the live items
        // copied.
        assert!(total > 30, "{total} steps");
        if before == erasing {
            assert!(total > 60, "{total} steps for the erasing save");
        }
        let (mut olds, mut news) = (0, 0);
        prefilled(&mut mem, before);
        let start = mem.clone();
        for cut in 0..=total {
            mem.copy_from_slice(&start);
            let mut s = store(&mut mem);
            s.load();
            let mut flash = s.into_flash();
            flash.cut_power_after(cut);
            let mut s = Store::new(flash, 0..BYTES as u32).unwrap();
            let result = s.save(&new);
            if cut < total {
                assert_eq!(result, Err(SaveError::Flash), "cut after {cut} of {total}");
            }
            // Start-up: the old settings or the new, whole; and the store takes the next save.
            let mut s = store(&mut mem);
            let loaded = s.load();
            assert_eq!(loaded.state, StoreState::Ok, "cut after {cut} of {total}");
            match loaded.settings {
                Some(x) if x == old => olds += 1,
                Some(x) if x == new => news += 1,
                other => panic!("cut after {cut} of {total}: {other:?}"),
            }
            let next = settings(before + 2);
            s.save(&next).unwrap();
            assert_eq!(
                store(&mut mem).load().settings,
                Some(next),
                "after cut {cut}"
            );
        }
        // Early cuts keep the old settings, late ones the new.
        assert!(olds > 0 && news > 0, "{olds} old, {news} new");
    }
}

#[test]
fn a_flipped_bit_in_the_newest_record_is_reported_not_passed_over() {
    let mut mem = vec![0xffu8; BYTES];
    prefilled(&mut mem, 5);
    // The newest record's bytes: the last place the new model's hash bytes appear... simpler:
    // find the newest record by its mass's bytes.
    let mass = settings(5).params.mass_kg.to_le_bytes();
    let at = mem
        .windows(8)
        .rposition(|w| w == mass)
        .expect("the newest record");
    mem[at] ^= 0x01;
    let loaded = store(&mut mem).load();
    assert_eq!(loaded.state, StoreState::Corrupt);
    assert_eq!(loaded.settings, None);
    // A flip in an older record changes nothing.
    prefilled(&mut mem, 5);
    let mass = settings(2).params.mass_kg.to_le_bytes();
    let at = mem.windows(8).position(|w| w == mass).unwrap();
    mem[at] ^= 0x80;
    let loaded = store(&mut mem).load();
    assert_eq!(
        (loaded.state, loaded.settings),
        (StoreState::Ok, Some(settings(5)))
    );
    assert_eq!(
        params_hash(&settings(5).params),
        params_hash(&loaded.settings.unwrap().params)
    );
}

#[test]
fn a_record_of_another_version_is_not_read() {
    let mut mem = vec![0xffu8; BYTES];
    {
        let mut map = MapStorage::<u8, _, _>::new(
            RamFlash::new(&mut mem),
            MapConfig::new(0..BYTES as u32),
            Cache::new_uncached(),
        );
        let mut buf = [0u8; 256];
        let mut record = vec![2u8, 0, 1, 0, 0, 0];
        record.extend_from_slice(&[0u8; 100]);
        block_on(map.store_item(&mut buf, &RECORD_KEY, &&record[..])).unwrap();
        block_on(map.store_item(&mut buf, &COUNT_KEY, &&1u32.to_le_bytes()[..])).unwrap();
    }
    let loaded = store(&mut mem).load();
    assert_eq!(
        (loaded.state, loaded.settings),
        (StoreState::OtherVersion, None)
    );
}

/// Start-up: the stored settings run; a store that holds nothing usable leaves the controller
/// on its preset and says why, naming the field the controller refused.
#[test]
fn start_up_runs_the_stored_settings_or_says_why_not() {
    use shared::control::{Controller, ControllerConfig, ModelSource};
    use shared::store::{StartUp, start_up};
    let mut mem = vec![0xffu8; BYTES];
    let fresh = || Controller::new(ControllerConfig::default(), RigId::Wires, 0.0).unwrap();
    let mut c = fresh();
    assert_eq!(
        start_up(&mut store(&mut mem), &mut c),
        StartUp::Fallback {
            state: StoreState::Empty,
            saves: 0,
            field: None
        }
    );
    assert_eq!(c.model().1.source, ModelSource::Preset(RigId::Wires));
    store(&mut mem).save(&settings(7)).unwrap();
    let mut c = fresh();
    assert_eq!(
        start_up(&mut store(&mut mem), &mut c),
        StartUp::Stored { save: 1 }
    );
    assert_eq!(c.settings(), settings(7));
    assert_eq!(c.model().1.source, ModelSource::Stored);
    // A record that reads but fails validation (a hammer of −1 kg: the store writes what it is
    // given) is refused by the controller, which keeps its preset.
    let mut bad = settings(8);
    bad.params.mass_kg = -1.0;
    store(&mut mem).save(&bad).unwrap();
    let mut c = fresh();
    let mut s = store(&mut mem);
    assert_eq!(
        start_up(&mut s, &mut c),
        StartUp::Fallback {
            state: StoreState::Invalid,
            saves: 2,
            field: Some("mass_kg")
        }
    );
    assert_eq!(s.status().state, StoreState::Invalid);
    assert_eq!(c.model().0, &RigId::Wires.preset());
}
