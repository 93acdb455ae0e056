//! Per-result integrity: the tag every [`JobResult`] carries over what it claims.
//!
//! A result's frame and set are checked against the jobs a connection holds, and its
//! pixel count against the set, but a flipped bit *inside* the radiance still decodes
//! (every `u32` is a valid RGB9E5 value): without a check over the payload a corrupted
//! result would put wrong pixels on screen. So each result carries
//! `tag = BLAKE3-keyed(K, domain ‖ frame ‖ set ‖ state_version ‖ radiance words)` and the
//! master recomputes it before anything else looks at the result.
//!
//! The key `K` is per connection: `K = HMAC-SHA256(secret, "gridlight result key v1" ‖
//! nonce)`, the nonce being the handshake's `Challenge`. Both sides can derive it, it
//! never travels, and it differs for every connection, so a result cannot be replayed on
//! another connection either.
//! - **With a shared secret**, only a holder of the secret can compute `K`: a man in the
//!   middle can neither alter pixels nor forge results of an authenticated worker.
//! - **Without a secret**, `K` is derived from the public nonce with an empty key: the tag
//!   is then a strong checksum (accidental corruption, a broken proxy, a buggy peer), not
//!   an authenticator — consistent with "no secret means a trusted network".
//!
//! A keyed cryptographic hash rather than a CRC or a non-cryptographic hash because the
//! same code then gives both properties. BLAKE3's keyed mode (a PRF, hence a MAC) rather
//! than HMAC-SHA256 (protocol v3) because the tag is computed twice for every result, on
//! the worker and on the master's single actor thread: BLAKE3 hashes a 19 kB result
//! (640×480, S = 64) several times faster with its SIMD chunk parallelism, and the master
//! thread is what bounds frames per second (`gridlight bench master`). The key is still
//! derived with HMAC-SHA256, once per connection, as the handshake is.

use hmac::{Hmac, Mac};
use sha2::Sha256;

use crate::auth::NONCE_LEN;
use crate::protocol::{FrameNo, JobResult, PackedRadiance, SetNo};
use crate::state::StateVersion;

type HmacSha256 = Hmac<Sha256>;

/// Bytes of a result's tag.
pub const TAG_LEN: usize = 32;

/// Separates the key derivation from the handshake's MAC over the same nonce.
const KEY_DOMAIN: &[u8] = b"gridlight result key v1";
/// Separates result tags from any other use of the key.
const TAG_DOMAIN: &[u8] = b"gridlight result v1";

/// The per-connection key results are tagged with.
#[derive(Clone)]
pub struct ResultKey([u8; 32]);

impl std::fmt::Debug for ResultKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("ResultKey(..)") // never print key material
    }
}

impl ResultKey {
    /// The key of the connection whose `Challenge` carried `nonce`.
    pub fn derive(secret: Option<&[u8]>, nonce: &[u8; NONCE_LEN]) -> Self {
        let mut m = keyed(secret.unwrap_or_default());
        m.update(KEY_DOMAIN);
        m.update(nonce);
        Self(m.finalize().into_bytes().into())
    }

    /// The tag of a result with these fields.
    pub fn tag(
        &self,
        frame: FrameNo,
        set: SetNo,
        state_version: StateVersion,
        radiance: &PackedRadiance,
    ) -> [u8; TAG_LEN] {
        let mut m = blake3::Hasher::new_keyed(&self.0);
        m.update(TAG_DOMAIN);
        m.update(&frame.to_le_bytes());
        m.update(&set.to_le_bytes());
        m.update(&state_version.to_le_bytes());
        match radiance {
            PackedRadiance::Rgb9e5(words) => {
                m.update(&[0]); // the variant, so that a future encoding cannot alias
                m.update(&(words.len() as u64).to_le_bytes());
                hash_le_words(&mut m, words);
            }
        }
        m.finalize().into()
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

    /// True when `r.tag` matches its fields; compares in constant time.
    pub fn verify(&self, r: &JobResult) -> bool {
        // blake3::Hash compares in constant time.
        blake3::Hash::from(self.tag(r.frame, r.set, r.state_version, &r.radiance))
            == blake3::Hash::from(r.tag)
    }
}

/// Feeds `words` as they travel (little-endian). On little-endian machines that is their
/// memory, hashed in one call so that BLAKE3 can work on many chunks at once.
fn hash_le_words(m: &mut blake3::Hasher, words: &[u32]) {
    if cfg!(target_endian = "little") {
        m.update(bytemuck::cast_slice(words));
    } else {
        for w in words {
            m.update(&w.to_le_bytes());
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
        let key = ResultKey::derive(Some(b"s".as_slice()), &[1; NONCE_LEN]);
        let r = result(&key);
        assert!(key.verify(&r));
        let mut changed = r.clone();
        let PackedRadiance::Rgb9e5(words) = &mut changed.radiance;
        words[417] ^= 1 << 20;
        assert!(!key.verify(&changed), "a flipped radiance bit went unnoticed");
        let changes: [fn(&mut JobResult); 5] = [
            |r: &mut JobResult| r.frame += 1,
            |r: &mut JobResult| r.set += 1,
            |r: &mut JobResult| r.state_version += 1,
            |r: &mut JobResult| r.tag[0] ^= 1,
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
    fn keys_differ_per_connection_and_per_secret() {
        let n1 = [1; NONCE_LEN];
        let n2 = [2; NONCE_LEN];
        let r = result(&ResultKey::derive(Some(b"s".as_slice()), &n1));
        assert!(
            !ResultKey::derive(Some(b"s".as_slice()), &n2).verify(&r),
            "replayable on another nonce"
        );
        assert!(
            !ResultKey::derive(Some(b"t".as_slice()), &n1).verify(&r),
            "forgeable without the secret"
        );
        assert!(!ResultKey::derive(None, &n1).verify(&r), "forgeable from the nonce alone");
        let open = result(&ResultKey::derive(None, &n1));
        assert!(ResultKey::derive(None, &n1).verify(&open));
    }

    #[test]
    fn the_key_is_not_the_handshake_mac() {
        let n = [3; NONCE_LEN];
        assert_ne!(ResultKey::derive(Some(b"s".as_slice()), &n).0, crate::auth::mac(b"s", &n));
    }
}
