#include "cia402/canopen.h"

#include <string.h>

uint16_t canopen_get_u16(const uint8_t *p)
{
    return (uint16_t)((uint16_t)p[0] | (uint16_t)((uint16_t)p[1] << 8));
}

uint32_t canopen_get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

void canopen_put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)(v & 0xFFu);
    p[1] = (uint8_t)(v >> 8);
}

void canopen_put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v & 0xFFu);
    p[1] = (uint8_t)((v >> 8) & 0xFFu);
    p[2] = (uint8_t)((v >> 16) & 0xFFu);
    p[3] = (uint8_t)(v >> 24);
}

int canopen_node_id_valid(uint8_t node_id)
{
    return node_id >= CANOPEN_NODE_ID_MIN && node_id <= CANOPEN_NODE_ID_MAX;
}

canopen_fn_t canopen_classify(const hal_can_frame_t *f, uint8_t *node_id)
{
    if (node_id != NULL) *node_id = 0;
    if (f == NULL || (f->flags & (HAL_CAN_FLAG_EXT | HAL_CAN_FLAG_RTR)) != 0u || f->id > HAL_CAN_STD_ID_MAX) {
        return CANOPEN_FN_OTHER;
    }
    if (f->id == CANOPEN_COB_NMT) return CANOPEN_FN_NMT;
    const uint8_t node = (uint8_t)(f->id & 0x7Fu);
    if (node == 0u) return CANOPEN_FN_OTHER; /* SYNC (0x080), TIME (0x100), ... */
    if (node_id != NULL) *node_id = node;
    switch (f->id & 0x780u) {
    case CANOPEN_COB_EMCY: return CANOPEN_FN_EMCY;
    case CANOPEN_COB_TPDO1: return CANOPEN_FN_TPDO1;
    case CANOPEN_COB_RPDO1: return CANOPEN_FN_RPDO1;
    case CANOPEN_COB_SDO_TX: return CANOPEN_FN_SDO_TX;
    case CANOPEN_COB_SDO_RX: return CANOPEN_FN_SDO_RX;
    case CANOPEN_COB_HEARTBEAT: return CANOPEN_FN_HEARTBEAT;
    default: break;
    }
    if (node_id != NULL) *node_id = 0;
    return CANOPEN_FN_OTHER;
}

static void frame_init(hal_can_frame_t *f, uint32_t id, uint8_t dlc)
{
    memset(f, 0, sizeof *f);
    f->id = id;
    f->dlc = dlc;
}

void canopen_nmt_frame(hal_can_frame_t *f, canopen_nmt_cmd_t cmd, uint8_t node_id)
{
    frame_init(f, CANOPEN_COB_NMT, 2);
    f->data[0] = (uint8_t)cmd;
    f->data[1] = node_id;
}

coslam_status_t canopen_heartbeat_frame(hal_can_frame_t *f, uint8_t node_id, canopen_nmt_state_t state)
{
    if (f == NULL || !canopen_node_id_valid(node_id)) return COSLAM_E_ARG;
    frame_init(f, CANOPEN_COB_HEARTBEAT + node_id, 1);
    f->data[0] = (uint8_t)state;
    return COSLAM_OK;
}

static void sdo_head(hal_can_frame_t *f, uint8_t node_id, uint8_t cmd, uint16_t index, uint8_t subindex)
{
    frame_init(f, CANOPEN_COB_SDO_RX + node_id, 8);
    f->data[0] = cmd;
    canopen_put_u16(&f->data[1], index);
    f->data[3] = subindex;
}

coslam_status_t canopen_sdo_download_frame(hal_can_frame_t *f, uint8_t node_id, uint16_t index, uint8_t subindex,
                                           uint32_t value, uint8_t size)
{
    if (f == NULL || !canopen_node_id_valid(node_id) || size < 1u || size > 4u) return COSLAM_E_ARG;
    /* ccs = 1 (download), e = 1 (expedited), s = 1 (size indicated), n = 4 - size */
    const uint8_t cmd = (uint8_t)(0x23u | (uint8_t)((4u - size) << 2));
    sdo_head(f, node_id, cmd, index, subindex);
    for (uint8_t i = 0; i < size; ++i) f->data[4 + i] = (uint8_t)((value >> (8u * i)) & 0xFFu);
    return COSLAM_OK;
}

coslam_status_t canopen_sdo_upload_frame(hal_can_frame_t *f, uint8_t node_id, uint16_t index, uint8_t subindex)
{
    if (f == NULL || !canopen_node_id_valid(node_id)) return COSLAM_E_ARG;
    sdo_head(f, node_id, 0x40u, index, subindex);
    return COSLAM_OK;
}

coslam_status_t canopen_sdo_abort_frame(hal_can_frame_t *f, uint8_t node_id, uint16_t index, uint8_t subindex,
                                        uint32_t abort_code)
{
    if (f == NULL || !canopen_node_id_valid(node_id)) return COSLAM_E_ARG;
    sdo_head(f, node_id, 0x80u, index, subindex);
    canopen_put_u32(&f->data[4], abort_code);
    return COSLAM_OK;
}

coslam_status_t canopen_sdo_parse_reply(const hal_can_frame_t *f, canopen_sdo_reply_t *r)
{
    if (f == NULL || r == NULL) return COSLAM_E_ARG;
    memset(r, 0, sizeof *r);
    if (f->dlc != 8u) return COSLAM_E_DRIVE_PROTOCOL;
    const uint8_t cmd = f->data[0];
    r->index = canopen_get_u16(&f->data[1]);
    r->subindex = f->data[3];
    if (cmd == 0x80u) {
        r->kind = CANOPEN_SDO_REPLY_ABORT;
        r->abort_code = canopen_get_u32(&f->data[4]);
        return COSLAM_OK;
    }
    if (cmd == 0x60u) {
        r->kind = CANOPEN_SDO_REPLY_DOWNLOAD_ACK;
        return COSLAM_OK;
    }
    if ((cmd & 0xE0u) == 0x40u) { /* scs = 2: initiate upload response */
        if ((cmd & 0x10u) != 0u) return COSLAM_E_DRIVE_PROTOCOL; /* reserved bit */
        if ((cmd & 0x02u) == 0u) {
            r->kind = CANOPEN_SDO_REPLY_SEGMENTED;
            return COSLAM_OK;
        }
        const uint8_t size = (cmd & 0x01u) != 0u ? (uint8_t)(4u - ((cmd >> 2) & 0x03u)) : 4u;
        r->kind = CANOPEN_SDO_REPLY_UPLOAD;
        r->size = size;
        for (uint8_t i = 0; i < size; ++i) r->value |= (uint32_t)f->data[4 + i] << (8u * i);
        return COSLAM_OK;
    }
    return COSLAM_E_DRIVE_PROTOCOL;
}

coslam_status_t canopen_emcy_parse(const hal_can_frame_t *f, canopen_emcy_t *e)
{
    if (f == NULL || e == NULL) return COSLAM_E_ARG;
    memset(e, 0, sizeof *e);
    if (f->dlc != 8u) return COSLAM_E_DRIVE_PROTOCOL;
    e->error_code = canopen_get_u16(&f->data[0]);
    e->error_register = f->data[2];
    memcpy(e->manufacturer, &f->data[3], sizeof e->manufacturer);
    return COSLAM_OK;
}

coslam_status_t canopen_heartbeat_parse(const hal_can_frame_t *f, canopen_nmt_state_t *state)
{
    if (f == NULL || state == NULL) return COSLAM_E_ARG;
    if (f->dlc != 1u) return COSLAM_E_DRIVE_PROTOCOL;
    *state = (canopen_nmt_state_t)(f->data[0] & 0x7Fu); /* bit 7: toggle bit of node guarding */
    return COSLAM_OK;
}
