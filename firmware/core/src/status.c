#include "coslam/status.h"

const char *coslam_status_str(coslam_status_t status)
{
    switch (status) {
    case COSLAM_OK: return "OK";
    case COSLAM_E_ARG: return "E_ARG";
    case COSLAM_E_CAPACITY: return "E_CAPACITY";
    case COSLAM_E_NUMERIC: return "E_NUMERIC";
    case COSLAM_E_NOT_PD: return "E_NOT_PD";
    case COSLAM_E_EMPTY: return "E_EMPTY";
    case COSLAM_E_DEGENERATE: return "E_DEGENERATE";
    case COSLAM_E_STALE: return "E_STALE";
    case COSLAM_E_MSG_TRUNCATED: return "E_MSG_TRUNCATED";
    case COSLAM_E_MSG_MAGIC: return "E_MSG_MAGIC";
    case COSLAM_E_MSG_VERSION: return "E_MSG_VERSION";
    case COSLAM_E_MSG_LENGTH: return "E_MSG_LENGTH";
    case COSLAM_E_MSG_CRC: return "E_MSG_CRC";
    case COSLAM_E_MSG_COUNT: return "E_MSG_COUNT";
    case COSLAM_E_MSG_NONFINITE: return "E_MSG_NONFINITE";
    case COSLAM_E_MSG_COVARIANCE: return "E_MSG_COVARIANCE";
    case COSLAM_E_MSG_FIELD: return "E_MSG_FIELD";
    case COSLAM_E_MSG_DUPLICATE: return "E_MSG_DUPLICATE";
    case COSLAM_E_MERGE_SELF: return "E_MERGE_SELF";
    case COSLAM_E_MERGE_STALE: return "E_MERGE_STALE";
    case COSLAM_E_MERGE_REPLAY: return "E_MERGE_REPLAY";
    case COSLAM_E_MERGE_DISAGREE: return "E_MERGE_DISAGREE";
    case COSLAM_E_MERGE_LOST: return "E_MERGE_LOST";
    case COSLAM_E_MERGE_RANGE: return "E_MERGE_RANGE";
    case COSLAM_E_MERGE_IMPLAUSIBLE: return "E_MERGE_IMPLAUSIBLE";
    case COSLAM_E_MERGE_BUSY: return "E_MERGE_BUSY";
    case COSLAM_E_MERGE_PENDING: return "E_MERGE_PENDING";
    case COSLAM_E_URG_TIMEOUT: return "E_URG_TIMEOUT";
    case COSLAM_E_URG_IO: return "E_URG_IO";
    case COSLAM_E_URG_CHECKSUM: return "E_URG_CHECKSUM";
    case COSLAM_E_URG_LINE: return "E_URG_LINE";
    case COSLAM_E_URG_GARBAGE: return "E_URG_GARBAGE";
    case COSLAM_E_URG_ECHO: return "E_URG_ECHO";
    case COSLAM_E_URG_STATUS: return "E_URG_STATUS";
    case COSLAM_E_URG_FIELD: return "E_URG_FIELD";
    case COSLAM_E_DRIVE_TIMEOUT: return "E_DRIVE_TIMEOUT";
    case COSLAM_E_DRIVE_ABORT: return "E_DRIVE_ABORT";
    case COSLAM_E_DRIVE_FAULT: return "E_DRIVE_FAULT";
    case COSLAM_E_DRIVE_BUS: return "E_DRIVE_BUS";
    case COSLAM_E_DRIVE_STATE: return "E_DRIVE_STATE";
    case COSLAM_E_DRIVE_PROTOCOL: return "E_DRIVE_PROTOCOL";
    case COSLAM_E_LINK: return "E_LINK";
    case COSLAM_E_STORAGE: return "E_STORAGE";
    case COSLAM_E_UNSUPPORTED: return "E_UNSUPPORTED";
    }
    return "E_UNKNOWN";
}
