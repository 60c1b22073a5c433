/*
 * coslam/crc32.h - CRC-32 as in IEEE 802.3 (Ethernet, zlib, PNG): polynomial
 * 0x04C11DB7 processed bit-reflected (0xEDB88320), initial value 0xFFFFFFFF,
 * final XOR 0xFFFFFFFF. Check value: CRC of the ASCII bytes "123456789" is
 * 0xCBF43926.
 *
 * Implementation: four bits per step through a const 16-entry table (64 bytes
 * of flash, no RAM, two table look-ups per byte). Stateless and re-entrant.
 */
#ifndef COSLAM_CRC32_H
#define COSLAM_CRC32_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/**
 * Extend a CRC-32 over `len` more bytes (zlib's convention).
 *
 * @param crc   the CRC of the bytes before `data`; 0 to start a new CRC.
 *              The initial value and final XOR are applied inside, so
 *              crc32_update(crc32_update(0, a, n), b, m) equals the CRC of
 *              the concatenation a || b.
 * @param data  read only; may be NULL when len is 0.
 * @param len   number of bytes.
 * @return      the CRC of everything so far (crc32_update(0, "123456789", 9)
 *              = 0xCBF43926; the CRC of nothing is 0).
 *
 * Time O(len); memory: none beyond the arguments; never fails.
 */
uint32_t crc32_update(uint32_t crc, const uint8_t *data, size_t len);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_CRC32_H */
