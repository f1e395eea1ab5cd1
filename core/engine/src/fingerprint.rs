//! Stable fingerprints of bytes, for names and checks that must not change between runs,
//! machines or versions (a resumed run's source file, a compiled-scene cache key, a prepared
//! dataset's cache name). FNV-1a, 64-bit: fast, dependency-free, not cryptographic.

/// FNV-1a's 64-bit offset basis: [`fnv1a`]'s usual starting value.
pub const FNV_OFFSET_BASIS: u64 = 0xcbf2_9ce4_8422_2325;

const FNV_PRIME: u64 = 0x0100_0000_01b3;

/// The 64-bit FNV-1a hash of `bytes`, starting from `basis` ([`FNV_OFFSET_BASIS`] for the
/// standard hash; another basis gives an independent one).
#[must_use]
pub fn fnv1a(bytes: &[u8], basis: u64) -> u64 {
    bytes.iter().fold(basis, |h, &b| (h ^ u64::from(b)).wrapping_mul(FNV_PRIME))
}

/// The standard 64-bit FNV-1a hash of `bytes` as 16 lowercase hex digits.
#[must_use]
pub fn fnv1a_hex(bytes: &[u8]) -> String {
    format!("{:016x}", fnv1a(bytes, FNV_OFFSET_BASIS))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hash_is_fnv1a_as_published() {
        // The reference test vectors of FNV-1a, 64-bit.
        assert_eq!(fnv1a(b"", FNV_OFFSET_BASIS), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(b"a", FNV_OFFSET_BASIS), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a(b"foobar", FNV_OFFSET_BASIS), 0x8594_4171_f739_67e8);
        assert_eq!(fnv1a_hex(b"a"), "af63dc4c8601ec8c");
        assert_ne!(fnv1a(b"a", 1), fnv1a(b"a", FNV_OFFSET_BASIS));
    }
}
