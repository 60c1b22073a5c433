/*
 * cia402/canopen.h - the CANopen (CiA 301) frames a master needs to run
 * CiA 402 drives: NMT commands, expedited SDO client requests and the
 * parsing of their replies, heartbeat and emergency (EMCY) messages.
 *
 * COB-IDs follow the predefined connection set (11-bit, node id 1..127):
 *     NMT        0x000          master -> all   [cs, node]
 *     EMCY       0x080 + node   drive  -> master [code lo, code hi, reg, 5 x mfr]
 *     TPDO1      0x180 + node   drive  -> master (mapping: cia402.h)
 *     RPDO1      0x200 + node   master -> drive  (mapping: cia402.h)
 *     SDO tx     0x580 + node   drive (server) -> master (client)
 *     SDO rx     0x600 + node   master (client) -> drive (server)
 *     heartbeat  0x700 + node   drive  -> master [NMT state]
 * Multi-byte fields are little-endian. Only expedited SDO transfers (up to
 * 4 data bytes) are supported; a segmented reply is a protocol error.
 *
 * All functions are pure, O(1), never block and keep no pointers.
 */
#ifndef CIA402_CANOPEN_H
#define CIA402_CANOPEN_H

#include <stdint.h>

#include "coslam/status.h"
#include "hal/hal_can.h"

#ifdef __cplusplus
extern "C" {
#endif

#define CANOPEN_COB_NMT 0x000u
#define CANOPEN_COB_EMCY 0x080u
#define CANOPEN_COB_TPDO1 0x180u
#define CANOPEN_COB_RPDO1 0x200u
#define CANOPEN_COB_SDO_TX 0x580u
#define CANOPEN_COB_SDO_RX 0x600u
#define CANOPEN_COB_HEARTBEAT 0x700u
#define CANOPEN_NODE_ID_MIN 1u
#define CANOPEN_NODE_ID_MAX 127u

/** NMT command specifiers (byte 0 of an NMT frame). */
typedef enum {
    CANOPEN_NMT_START = 0x01,
    CANOPEN_NMT_STOP = 0x02,
    CANOPEN_NMT_ENTER_PREOP = 0x80,
    CANOPEN_NMT_RESET_NODE = 0x81,
    CANOPEN_NMT_RESET_COMM = 0x82,
} canopen_nmt_cmd_t;

/** NMT states as carried by heartbeat frames. */
typedef enum {
    CANOPEN_NMT_STATE_BOOTUP = 0x00,
    CANOPEN_NMT_STATE_STOPPED = 0x04,
    CANOPEN_NMT_STATE_OPERATIONAL = 0x05,
    CANOPEN_NMT_STATE_PREOP = 0x7F,
} canopen_nmt_state_t;

/* SDO abort codes (CiA 301, 7.2.4.3.17) used by this driver and the emulator. */
#define CANOPEN_SDO_ABORT_TIMEOUT 0x05040000u      /**< SDO protocol timed out */
#define CANOPEN_SDO_ABORT_COMMAND 0x05040001u      /**< command specifier not valid or unknown */
#define CANOPEN_SDO_ABORT_WRITE_ONLY 0x06010001u   /**< attempt to read a write-only object */
#define CANOPEN_SDO_ABORT_READ_ONLY 0x06010002u    /**< attempt to write a read-only object */
#define CANOPEN_SDO_ABORT_NO_OBJECT 0x06020000u    /**< object does not exist */
#define CANOPEN_SDO_ABORT_LENGTH 0x06070010u       /**< data type / length does not match */
#define CANOPEN_SDO_ABORT_NO_SUBINDEX 0x06090011u  /**< sub-index does not exist */
#define CANOPEN_SDO_ABORT_VALUE_RANGE 0x06090030u  /**< value range of parameter exceeded */
#define CANOPEN_SDO_ABORT_GENERAL 0x08000000u      /**< general error */
#define CANOPEN_SDO_ABORT_DEVICE_STATE 0x08000022u /**< not possible in the present device state */

/** Function of a received frame, from its COB-ID. */
typedef enum {
    CANOPEN_FN_OTHER = 0,  /**< not one of the kinds below (or an extended/remote frame) */
    CANOPEN_FN_NMT,
    CANOPEN_FN_EMCY,
    CANOPEN_FN_TPDO1,
    CANOPEN_FN_RPDO1,
    CANOPEN_FN_SDO_TX,
    CANOPEN_FN_SDO_RX,
    CANOPEN_FN_HEARTBEAT,
} canopen_fn_t;

/** Kind of an SDO server reply (canopen_sdo_parse_reply). */
typedef enum {
    CANOPEN_SDO_REPLY_DOWNLOAD_ACK = 1, /**< 0x60: the write was accepted */
    CANOPEN_SDO_REPLY_UPLOAD = 2,       /**< 0x4x expedited: value and size set */
    CANOPEN_SDO_REPLY_ABORT = 3,        /**< 0x80: abort_code set */
    CANOPEN_SDO_REPLY_SEGMENTED = 4,    /**< 0x41 / 0x40: a non-expedited upload, not supported */
} canopen_sdo_reply_kind_t;

typedef struct {
    canopen_sdo_reply_kind_t kind;
    uint16_t index;
    uint8_t subindex;
    uint8_t size;        /**< UPLOAD: data bytes 1..4 (4 when the size is not indicated) */
    uint32_t value;      /**< UPLOAD: the data, zero-extended little-endian */
    uint32_t abort_code; /**< ABORT */
} canopen_sdo_reply_t;

typedef struct {
    uint16_t error_code;     /**< CiA 301 emergency error code; 0x0000 = error reset / no error */
    uint8_t error_register;  /**< object 0x1001 */
    uint8_t manufacturer[5]; /**< manufacturer-specific bytes */
} canopen_emcy_t;

/** 1 if node_id is in 1..127. */
int canopen_node_id_valid(uint8_t node_id);

/**
 * Function and node id of a frame. Extended and remote frames are
 * CANOPEN_FN_OTHER. *node_id (may be NULL) gets id & 0x7F (0 for NMT).
 */
canopen_fn_t canopen_classify(const hal_can_frame_t *f, uint8_t *node_id);

/** NMT command frame for node_id (0 = all nodes): id 0x000, dlc 2, [cmd, node]. */
void canopen_nmt_frame(hal_can_frame_t *f, canopen_nmt_cmd_t cmd, uint8_t node_id);

/**
 * Expedited SDO download (write) request to node_id: id 0x600+node, dlc 8,
 * [0x23 | (4 - size) << 2, index lo, index hi, sub, value LE (size bytes), 0...].
 * size 1..4 (COSLAM_E_ARG otherwise, or for a bad node id).
 */
coslam_status_t canopen_sdo_download_frame(hal_can_frame_t *f, uint8_t node_id, uint16_t index, uint8_t subindex,
                                           uint32_t value, uint8_t size);

/** SDO upload (read) request: id 0x600+node, dlc 8, [0x40, index lo, index hi, sub, 0, 0, 0, 0]. */
coslam_status_t canopen_sdo_upload_frame(hal_can_frame_t *f, uint8_t node_id, uint16_t index, uint8_t subindex);

/** SDO abort from the client: id 0x600+node, dlc 8, [0x80, index lo, hi, sub, code LE]. */
coslam_status_t canopen_sdo_abort_frame(hal_can_frame_t *f, uint8_t node_id, uint16_t index, uint8_t subindex,
                                        uint32_t abort_code);

/**
 * Parse an SDO server reply (id 0x580+node, dlc 8). Returns COSLAM_OK;
 * COSLAM_E_DRIVE_PROTOCOL for dlc != 8 or an unknown server command
 * specifier; COSLAM_E_ARG NULL.
 */
coslam_status_t canopen_sdo_parse_reply(const hal_can_frame_t *f, canopen_sdo_reply_t *r);

/** Parse an EMCY frame (dlc 8). COSLAM_E_DRIVE_PROTOCOL for another dlc. */
coslam_status_t canopen_emcy_parse(const hal_can_frame_t *f, canopen_emcy_t *e);

/** Heartbeat of node_id (a producer's): id 0x700+node, dlc 1, [state]. COSLAM_E_ARG bad node id. */
coslam_status_t canopen_heartbeat_frame(hal_can_frame_t *f, uint8_t node_id, canopen_nmt_state_t state);

/** Parse a heartbeat (dlc 1, state in bit 0..6). COSLAM_E_DRIVE_PROTOCOL for another dlc. */
coslam_status_t canopen_heartbeat_parse(const hal_can_frame_t *f, canopen_nmt_state_t *state);

/** Little-endian helpers on a frame's data. */
uint16_t canopen_get_u16(const uint8_t *p);
uint32_t canopen_get_u32(const uint8_t *p);
void canopen_put_u16(uint8_t *p, uint16_t v);
void canopen_put_u32(uint8_t *p, uint32_t v);

#ifdef __cplusplus
}
#endif

#endif /* CIA402_CANOPEN_H */
