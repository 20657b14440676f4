//! A rig model's canonical bytes ([`params_bytes`]: postcard, the fields in declaration order,
//! every `f64` as its 8 bytes) and their CRC-32 ([`params_hash`], CRC-32/ISO-HDLC, as zlib's):
//! the board and the desktop hash the same bits to the same number, so `id`, `status` and a log
//! say which model a target frequency was computed from, and a push is verified by reading the
//! hash back.

use super::rig::RigParams;

/// Upper bound of [`params_bytes`]' length: 13 `f64` fields at most and the two enum tags.
pub const PARAMS_BYTES: usize = 128;

/// The model's canonical bytes, written into `out`; their length.
///
/// # Errors
/// `out` too short (never with [`PARAMS_BYTES`]: tested).
pub fn params_bytes(params: &RigParams, out: &mut [u8]) -> Result<usize, postcard::Error> {
    postcard::to_slice(params, out).map(|s| s.len())
}

/// The CRC-32 of the model's canonical bytes.
pub fn params_hash(params: &RigParams) -> u32 {
    let mut buf = [0u8; PARAMS_BYTES];
    // Never fails with PARAMS_BYTES (tested): a failure would hash nothing, never panic.
    let n = params_bytes(params, &mut buf).unwrap_or(0);
    crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC).checksum(&buf[..n])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{ContactLaw, ContactLawKind, ModelEdit, RigId};

    #[test]
    fn every_model_fits_and_round_trips_and_each_bit_changes_the_hash() {
        let mut hashes = std::vec::Vec::new();
        for rig in RigId::ALL {
            for kind in ContactLawKind::ALL {
                let p = rig.preset().edited(ModelEdit::Law(kind)).unwrap();
                let mut buf = [0u8; PARAMS_BYTES];
                let n = params_bytes(&p, &mut buf).unwrap();
                let back: RigParams = postcard::from_bytes(&buf[..n]).unwrap();
                assert_eq!(back, p);
                hashes.push(params_hash(&p));
                // One ulp of the mass is another model.
                let mut q = p;
                q.mass_kg = f64::from_bits(q.mass_kg.to_bits() + 1);
                assert_ne!(params_hash(&q), params_hash(&p));
            }
        }
        hashes.sort_unstable();
        hashes.dedup();
        assert_eq!(hashes.len(), RigId::ALL.len() * ContactLawKind::ALL.len());
        // The hash is zlib's CRC-32 of the bytes (an independent implementation's value for
        // the check string, as the CRC catalogue gives it).
        assert_eq!(
            crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC).checksum(b"123456789"),
            0xcbf4_3926
        );
        let _ = ContactLaw::identified();
    }
}
