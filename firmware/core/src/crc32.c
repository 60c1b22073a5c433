#include "coslam/crc32.h"

/* CRC of each 4-bit value, reflected polynomial 0xEDB88320: entry i is i
 * shifted four times through the bitwise CRC register. The test rebuilds it
 * bit by bit. */
static const uint32_t crc32_nibble_table[16] = {
    0x00000000U, 0x1DB71064U, 0x3B6E20C8U, 0x26D930ACU, 0x76DC4190U, 0x6B6B51F4U,
    0x4DB26158U, 0x5005713CU, 0xEDB88320U, 0xF00F9344U, 0xD6D6A3E8U, 0xCB61B38CU,
    0x9B64C2B0U, 0x86D3D2D4U, 0xA00AE278U, 0xBDBDF21CU,
};

uint32_t crc32_update(uint32_t crc, const uint8_t *data, size_t len)
{
    uint32_t c = ~crc;
    for (size_t i = 0; i < len; ++i) {
        c ^= (uint32_t)data[i];
        c = (c >> 4) ^ crc32_nibble_table[c & 0x0FU];
        c = (c >> 4) ^ crc32_nibble_table[c & 0x0FU];
    }
    return ~c;
}
