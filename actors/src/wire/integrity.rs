//! Per-result integrity: what makes sure an altered result never reaches an image.
//!
//! A result's frame and set are checked against the jobs a connection holds, and its
//! pixel count against the set, but a flipped bit *inside* the radiance still decodes
//! (every `u32` is a valid RGB9E5 value): without a check over the payload a corrupted
//! result would put wrong pixels on screen. What checks it depends on the connection:
//! - **With a shared secret** the connection is encrypted (`wire::channel`): every record
//!   carries the channel's AEAD tag, checked before a byte of it is decoded, so an altered
//!   result ends the connection before it is a message. A second tag inside the result
//!   would prove nothing more and cost as much again, so results carry none
//!   ([`ResultKey::Channel`]). (Until protocol 8 they carried a keyed BLAKE3 tag, which
//!   cost a third of the master's throughput in `gridlight bench master`.)
//! - **Without a secret** nothing can authenticate (anyone can compute any key), so the
//!   tag is a checksum against accidental corruption (a broken proxy, a buggy peer, the bit
//!   flips TCP's 16-bit sum misses): `tag = XXH3-128(domain ‖ frame ‖ set ‖ state_version
//!   ‖ radiance words)` seeded with `K = HMAC-SHA256("", "gridlight result key v1" ‖
//!   nonce)`, the nonce being the handshake's `Challenge`, so the seed differs per
//!   connection and a result cannot be replayed on another one by accident. The master
//!   recomputes it before anything else looks at the result.

use hmac::{Hmac, Mac};
use sha2::Sha256;
use subtle::ConstantTimeEq;
use xxhash_rust::xxh3::Xxh3;

use crate::scene::state::StateVersion;
use crate::wire::auth::NONCE_LEN;
use crate::wire::protocol::{FrameNo, JobResult, PackedRadiance, SetNo};

type HmacSha256 = Hmac<Sha256>;

/// Bytes of a result's tag.
pub const TAG_LEN: usize = 16;

/// Separates the key derivation from the handshake's MAC over the same nonce.
const KEY_DOMAIN: &[u8] = b"gridlight result key v1";
/// Separates result tags from any other use of the key.
const TAG_DOMAIN: &[u8] = b"gridlight result v1";

/// How a connection's results are checked.
#[derive(Clone)]
pub enum ResultKey {
    /// The connection is encrypted: the channel authenticates every byte, results carry
    /// no tag of their own.
    Channel,
    /// No secret: tags are XXH3-128 with this seed (a checksum).
    Checksum(u64),
}

impl std::fmt::Debug for ResultKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Never print key material.
        f.write_str(match self {
            ResultKey::Channel => "ResultKey::Channel",
            ResultKey::Checksum(_) => "ResultKey::Checksum(..)",
        })
    }
}

impl ResultKey {
    /// The checksum key of a plain connection whose `Challenge` carried `nonce`.
    pub fn checksum(nonce: &[u8; NONCE_LEN]) -> Self {
        let mut m = keyed(b"");
        m.update(KEY_DOMAIN);
        m.update(nonce);
        let k: [u8; 32] = m.finalize().into_bytes().into();
        ResultKey::Checksum(u64::from_le_bytes(k[..8].try_into().expect("8 bytes")))
    }

    /// The key of a connection: [`ResultKey::Channel`] when it is encrypted, else the
    /// checksum of its `Challenge` nonce.
    pub fn for_connection(encrypted: bool, nonce: &[u8; NONCE_LEN]) -> Self {
        if encrypted {
            ResultKey::Channel
        } else {
            ResultKey::checksum(nonce)
        }
    }

    /// The tag a result with these fields carries (`None` on an encrypted connection).
    pub fn tag(
        &self,
        frame: FrameNo,
        set: SetNo,
        state_version: StateVersion,
        radiance: &PackedRadiance,
    ) -> Option<[u8; TAG_LEN]> {
        let ResultKey::Checksum(seed) = self else { return None };
        let fields = |update: &mut dyn FnMut(&[u8])| {
            update(TAG_DOMAIN);
            update(&frame.to_le_bytes());
            update(&set.to_le_bytes());
            update(&state_version.to_le_bytes());
            match radiance {
                PackedRadiance::Rgb9e5(words) => {
                    update(&[0]); // the variant, so that a future encoding cannot alias
                    update(&(words.len() as u64).to_le_bytes());
                    feed_le_words(update, words);
                }
            }
        };
        let mut m = Xxh3::with_seed(*seed);
        fields(&mut |b| m.update(b));
        Some(m.digest128().to_le_bytes())
    }

    /// A result with its tag computed over the other fields.
    pub fn seal(
        &self,
        frame: FrameNo,
        set: SetNo,
        state_version: StateVersion,
        radiance: PackedRadiance,
        render_us: u64,
    ) -> JobResult {
        let tag = self.tag(frame, set, state_version, &radiance);
        JobResult { frame, set, state_version, radiance, render_us, tag }
    }

    /// True when `r.tag` is what its fields call for: none on an encrypted connection
    /// (the channel checked every byte), the matching checksum on a plain one.
    pub fn verify(&self, r: &JobResult) -> bool {
        match (self.tag(r.frame, r.set, r.state_version, &r.radiance), &r.tag) {
            (None, None) => true,
            (Some(want), Some(got)) => want.ct_eq(got).into(),
            _ => false,
        }
    }
}

/// Feeds `words` as they travel (little-endian). On little-endian machines that is their
/// memory, fed in one call so that the hash can work on long runs at once.
fn feed_le_words(update: &mut dyn FnMut(&[u8]), words: &[u32]) {
    if cfg!(target_endian = "little") {
        update(bytemuck::cast_slice(words));
    } else {
        for w in words {
            update(&w.to_le_bytes());
        }
    }
}

fn keyed(key: &[u8]) -> HmacSha256 {
    // HMAC accepts keys of any length, so this cannot fail.
    <HmacSha256 as Mac>::new_from_slice(key).expect("HMAC takes keys of any length")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn result(key: &ResultKey) -> JobResult {
        key.seal(7, 3, 2, PackedRadiance::Rgb9e5((0..600).collect()), 9)
    }

    #[test]
    fn a_sealed_result_verifies_and_any_changed_field_does_not() {
        let key = ResultKey::checksum(&[1; NONCE_LEN]);
        let r = result(&key);
        assert!(key.verify(&r), "{key:?}");
        let mut changed = r.clone();
        let PackedRadiance::Rgb9e5(words) = &mut changed.radiance;
        words[417] ^= 1 << 20;
        assert!(!key.verify(&changed), "a flipped radiance bit went unnoticed");
        let changes: [fn(&mut JobResult); 7] = [
            |r: &mut JobResult| r.frame += 1,
            |r: &mut JobResult| r.set += 1,
            |r: &mut JobResult| r.state_version += 1,
            |r: &mut JobResult| r.tag.as_mut().expect("tag")[0] ^= 1,
            |r: &mut JobResult| r.tag.as_mut().expect("tag")[TAG_LEN - 1] ^= 0x80,
            |r: &mut JobResult| r.tag = None,
            |r: &mut JobResult| {
                let PackedRadiance::Rgb9e5(w) = &mut r.radiance;
                w.pop();
            },
        ];
        for change in changes {
            let mut c = r.clone();
            change(&mut c);
            assert!(!key.verify(&c), "{c:?}");
        }
        // render_us is advisory (timing), not pixels: not covered.
        let mut timing = r;
        timing.render_us += 1;
        assert!(key.verify(&timing));
    }

    #[test]
    fn checksums_differ_per_connection() {
        let r = result(&ResultKey::checksum(&[1; NONCE_LEN]));
        assert!(!ResultKey::checksum(&[2; NONCE_LEN]).verify(&r), "not bound to the connection");
    }

    #[test]
    fn an_encrypted_connection_carries_no_tag_and_refuses_one() {
        let r = result(&ResultKey::Channel);
        assert_eq!(r.tag, None, "a tag the channel makes redundant");
        assert!(ResultKey::Channel.verify(&r));
        let tagged = result(&ResultKey::checksum(&[1; NONCE_LEN]));
        assert!(!ResultKey::Channel.verify(&tagged), "a checksummed result on an encrypted link");
        assert!(
            !ResultKey::checksum(&[1; NONCE_LEN]).verify(&r),
            "an untagged result on a plain link"
        );
    }
}
