//! Per-result integrity: the tag every [`JobResult`] carries over what it claims.
//!
//! A result's frame and set are checked against the jobs a connection holds, and its
//! pixel count against the set, but a flipped bit *inside* the radiance still decodes
//! (every `u32` is a valid RGB9E5 value): without a check over the payload a corrupted
//! result would put wrong pixels on screen. So each result carries a 128-bit
//! `tag = H(domain ‖ frame ‖ set ‖ state_version ‖ radiance words)` under a
//! per-connection key, and the master recomputes it before anything else looks at it.
//!
//! The key material is per connection: `K = HMAC-SHA256(secret, "gridlight result key
//! v1" ‖ nonce)`, the nonce being the handshake's `Challenge`. Both sides can derive it,
//! it never travels, and it differs for every connection, so a result cannot be replayed
//! on another connection either. `H` depends on what the tag has to prove:
//! - **With a shared secret** the tag is an authenticator: keyed BLAKE3 under `K`,
//!   truncated to 128 bits (BLAKE3's keyed mode is a PRF, hence a MAC). Only a holder of
//!   the secret can compute `K`: a man in the middle can neither alter pixels nor forge
//!   results of an authenticated worker.
//! - **Without a secret** `K` follows from the public nonce, so no tag could
//!   authenticate; it is a checksum against accidental corruption (a broken proxy, a
//!   buggy peer, the bit flips TCP's 16-bit sum misses): XXH3-128 seeded with `K`.
//!   A cryptographic hash would buy nothing here and cost much: BLAKE3 over the 19 kB of
//!   a 640×480, S = 64 result took a fifth of the machine in `gridlight bench master`
//!   (once on the worker, once on the master's single actor thread); XXH3 is an order
//!   of magnitude faster.

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

/// The per-connection key results are tagged with.
#[derive(Clone)]
pub enum ResultKey {
    /// A shared secret is configured: tags are keyed BLAKE3 (a MAC).
    Authenticated([u8; 32]),
    /// No secret: tags are XXH3-128 with this seed (a checksum).
    Checksum(u64),
}

impl std::fmt::Debug for ResultKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Never print key material.
        f.write_str(match self {
            ResultKey::Authenticated(_) => "ResultKey::Authenticated(..)",
            ResultKey::Checksum(_) => "ResultKey::Checksum(..)",
        })
    }
}

impl ResultKey {
    /// The key of the connection whose `Challenge` carried `nonce`.
    pub fn derive(secret: Option<&[u8]>, nonce: &[u8; NONCE_LEN]) -> Self {
        let mut m = keyed(secret.unwrap_or_default());
        m.update(KEY_DOMAIN);
        m.update(nonce);
        let k: [u8; 32] = m.finalize().into_bytes().into();
        match secret {
            Some(_) => ResultKey::Authenticated(k),
            None => ResultKey::Checksum(u64::from_le_bytes(k[..8].try_into().expect("8 bytes"))),
        }
    }

    /// The tag of a result with these fields.
    pub fn tag(
        &self,
        frame: FrameNo,
        set: SetNo,
        state_version: StateVersion,
        radiance: &PackedRadiance,
    ) -> [u8; TAG_LEN] {
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
        match self {
            ResultKey::Authenticated(key) => {
                let mut m = blake3::Hasher::new_keyed(key);
                fields(&mut |b| {
                    m.update(b);
                });
                let mut tag = [0; TAG_LEN];
                m.finalize_xof().fill(&mut tag);
                tag
            }
            ResultKey::Checksum(seed) => {
                let mut m = Xxh3::with_seed(*seed);
                fields(&mut |b| m.update(b));
                m.digest128().to_le_bytes()
            }
        }
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
        self.tag(r.frame, r.set, r.state_version, &r.radiance).ct_eq(&r.tag).into()
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
        // Both kinds of key: the MAC (secret) and the checksum (no secret).
        for secret in [Some(b"s".as_slice()), None] {
            let key = ResultKey::derive(secret, &[1; NONCE_LEN]);
            let r = result(&key);
            assert!(key.verify(&r), "{key:?}");
            let mut changed = r.clone();
            let PackedRadiance::Rgb9e5(words) = &mut changed.radiance;
            words[417] ^= 1 << 20;
            assert!(!key.verify(&changed), "{key:?}: a flipped radiance bit went unnoticed");
            let changes: [fn(&mut JobResult); 6] = [
                |r: &mut JobResult| r.frame += 1,
                |r: &mut JobResult| r.set += 1,
                |r: &mut JobResult| r.state_version += 1,
                |r: &mut JobResult| r.tag[0] ^= 1,
                |r: &mut JobResult| r.tag[TAG_LEN - 1] ^= 0x80,
                |r: &mut JobResult| {
                    let PackedRadiance::Rgb9e5(w) = &mut r.radiance;
                    w.pop();
                },
            ];
            for change in changes {
                let mut c = r.clone();
                change(&mut c);
                assert!(!key.verify(&c), "{key:?}: {c:?}");
            }
            // render_us is advisory (timing), not pixels: not covered.
            let mut timing = r;
            timing.render_us += 1;
            assert!(key.verify(&timing), "{key:?}");
        }
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
        assert!(
            !ResultKey::derive(None, &n2).verify(&open),
            "checksum not bound to the connection"
        );
        assert!(
            !ResultKey::derive(Some(b"".as_slice()), &n1).verify(&open),
            "checksum taken for a MAC"
        );
    }

    #[test]
    fn the_key_is_not_the_handshake_mac() {
        let n = [3; NONCE_LEN];
        let ResultKey::Authenticated(k) = ResultKey::derive(Some(b"s".as_slice()), &n) else {
            panic!("a secret gives an authenticating key");
        };
        assert_ne!(k, crate::wire::auth::mac(b"s", &n));
    }
}
