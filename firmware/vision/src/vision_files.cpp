// The colour table file and the range model file (formats in vision.h).
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "coslam/crc32.h"
#include "vision/vision.h"

namespace {

const uint8_t kMagic[4] = {'C', 'V', 'L', 'T'};
constexpr uint16_t kVersion = 1;

void put_u16(uint8_t *p, uint16_t v)
{
    p[0] = static_cast<uint8_t>(v);
    p[1] = static_cast<uint8_t>(v >> 8);
}

void put_u32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}

uint16_t get_u16(const uint8_t *p)
{
    return static_cast<uint16_t>(p[0] | (p[1] << 8));
}

uint32_t get_u32(const uint8_t *p)
{
    uint32_t v = 0;
    for (int i = 3; i >= 0; --i) v = (v << 8) | p[i];
    return v;
}

std::string trim(const std::string &s)
{
    const size_t a = s.find_first_not_of(" \t\r\n");
    if (a == std::string::npos) return "";
    const size_t b = s.find_last_not_of(" \t\r\n");
    return s.substr(a, b - a + 1);
}

// Parse exactly n doubles separated by blanks; false otherwise.
bool parse_doubles(const std::string &v, double *out, int n)
{
    const char *p = v.c_str();
    for (int i = 0; i < n; ++i) {
        char *end = nullptr;
        errno = 0;
        const double d = std::strtod(p, &end);
        if (end == p || errno != 0 || !std::isfinite(d)) return false;
        out[i] = d;
        p = end;
    }
    while (*p == ' ' || *p == '\t') ++p;
    return *p == '\0';
}

}  // namespace

extern "C" {

const char *vision_status_name(vision_status_t st)
{
    switch (st) {
    case VISION_OK: return "VISION_OK";
    case VISION_E_ARG: return "VISION_E_ARG";
    case VISION_E_IO: return "VISION_E_IO";
    case VISION_E_FORMAT: return "VISION_E_FORMAT";
    case VISION_E_CRC: return "VISION_E_CRC";
    case VISION_E_CAPACITY: return "VISION_E_CAPACITY";
    case VISION_E_NOMEM: return "VISION_E_NOMEM";
    }
    return "VISION_E_?";
}

vision_status_t vision_lut_encode(const vision_lut_t *lut, uint8_t *buf, size_t cap)
{
    if (lut == nullptr || buf == nullptr || cap < VISION_LUT_FILE_BYTES) return VISION_E_ARG;
    std::memset(buf, 0, VISION_LUT_HEADER_BYTES);
    std::memcpy(buf, kMagic, 4);
    put_u16(buf + 4, kVersion);
    buf[6] = VISION_LUT_BITS;
    buf[7] = VISION_N_COLOURS;
    put_u32(buf + 8, VISION_LUT_SIZE);
    put_u32(buf + 12, 0);
    for (size_t i = 0; i < 31 && lut->method[i] != '\0'; ++i) buf[16 + i] = static_cast<uint8_t>(lut->method[i]);
    std::memcpy(buf + VISION_LUT_HEADER_BYTES, lut->table, VISION_LUT_SIZE);
    const uint32_t crc = crc32_update(0, buf, VISION_LUT_HEADER_BYTES + VISION_LUT_SIZE);
    put_u32(buf + VISION_LUT_HEADER_BYTES + VISION_LUT_SIZE, crc);
    return VISION_OK;
}

vision_status_t vision_lut_decode(vision_lut_t *lut, const uint8_t *buf, size_t len)
{
    if (lut == nullptr || buf == nullptr) return VISION_E_ARG;
    if (len != VISION_LUT_FILE_BYTES) return VISION_E_FORMAT;
    if (std::memcmp(buf, kMagic, 4) != 0 || get_u16(buf + 4) != kVersion || buf[6] != VISION_LUT_BITS ||
        buf[7] != VISION_N_COLOURS || get_u32(buf + 8) != VISION_LUT_SIZE) {
        return VISION_E_FORMAT;
    }
    const uint32_t crc = crc32_update(0, buf, VISION_LUT_HEADER_BYTES + VISION_LUT_SIZE);
    if (crc != get_u32(buf + VISION_LUT_HEADER_BYTES + VISION_LUT_SIZE)) return VISION_E_CRC;
    const uint8_t *t = buf + VISION_LUT_HEADER_BYTES;
    for (size_t i = 0; i < VISION_LUT_SIZE; ++i) {
        if (t[i] >= VISION_N_COLOURS) return VISION_E_FORMAT;
    }
    std::memcpy(lut->table, t, VISION_LUT_SIZE);
    std::memset(lut->method, 0, sizeof lut->method);
    for (size_t i = 0; i < 31 && buf[16 + i] != 0; ++i) lut->method[i] = static_cast<char>(buf[16 + i]);
    return VISION_OK;
}

vision_status_t vision_lut_load(vision_lut_t *lut, const char *path)
{
    if (lut == nullptr || path == nullptr) return VISION_E_ARG;
    FILE *f = std::fopen(path, "rb");
    if (f == nullptr) return VISION_E_IO;
    static thread_local uint8_t buf[VISION_LUT_FILE_BYTES + 1];
    const size_t n = std::fread(buf, 1, sizeof buf, f);
    const bool err = std::ferror(f) != 0;
    std::fclose(f);
    if (err) return VISION_E_IO;
    return vision_lut_decode(lut, buf, n);
}

vision_status_t vision_lut_save(const vision_lut_t *lut, const char *path)
{
    if (lut == nullptr || path == nullptr) return VISION_E_ARG;
    static thread_local uint8_t buf[VISION_LUT_FILE_BYTES];
    const vision_status_t st = vision_lut_encode(lut, buf, sizeof buf);
    if (st != VISION_OK) return st;
    FILE *f = std::fopen(path, "wb");
    if (f == nullptr) return VISION_E_IO;
    const size_t n = std::fwrite(buf, 1, sizeof buf, f);
    const int rc = std::fclose(f);
    return (n == sizeof buf && rc == 0) ? VISION_OK : VISION_E_IO;
}

vision_range_model_t vision_range_model_pinhole(void)
{
    vision_range_model_t m;
    m.landmark = vision_range_fit_t{{VISION_LANDMARK_RADIUS_M, 1.0, 0.0}, 0.05, 0.05, 1.0 * 3.14159265358979 / 180.0};
    m.robot = vision_range_fit_t{{VISION_ROBOT_MARKER_RADIUS_M, 1.0, 0.0}, 0.05, 0.05, 1.0 * 3.14159265358979 / 180.0};
    return m;
}

double vision_range_pinhole(double focal_px, double h_px, double bearing_rad)
{
    return focal_px * VISION_MARKER_HEIGHT_M / (h_px * std::cos(bearing_rad));
}

double vision_range_from_height(const vision_range_fit_t *fit, double focal_px, double h_px, double bearing_rad)
{
    const double rp = vision_range_pinhole(focal_px, h_px, bearing_rad);
    return fit->c[0] + fit->c[1] * rp + fit->c[2] * rp * rp;
}

vision_status_t vision_range_model_load(vision_range_model_t *m, const char *path)
{
    if (m == nullptr || path == nullptr) return VISION_E_ARG;
    FILE *f = std::fopen(path, "r");
    if (f == nullptr) return VISION_E_IO;
    vision_range_model_t out{};
    unsigned seen = 0;  // bit per key
    bool format_ok = false, bad = false;
    char line[512];
    while (std::fgets(line, sizeof line, f) != nullptr) {
        std::string s(line);
        const size_t hash = s.find('#');
        if (hash != std::string::npos) s.resize(hash);
        s = trim(s);
        if (s.empty()) continue;
        const size_t eq = s.find('=');
        if (eq == std::string::npos) {
            bad = true;
            break;
        }
        const std::string key = trim(s.substr(0, eq));
        const std::string val = trim(s.substr(eq + 1));
        if (key == "format") {
            format_ok = val == "coslam-vision-range 1";
            if (!format_ok) bad = true;
            continue;
        }
        vision_range_fit_t *fit = nullptr;
        std::string sub;
        unsigned base = 0;
        if (key.rfind("landmark.", 0) == 0) {
            fit = &out.landmark;
            sub = key.substr(9);
        } else if (key.rfind("robot.", 0) == 0) {
            fit = &out.robot;
            sub = key.substr(6);
            base = 4;
        } else {
            bad = true;
            break;
        }
        double v[3];
        if (sub == "c" && parse_doubles(val, v, 3)) {
            std::memcpy(fit->c, v, sizeof v);
            seen |= 1u << base;
        } else if (sub == "range_sd_m" && parse_doubles(val, v, 1) && v[0] >= 0.0) {
            fit->range_sd_m = v[0];
            seen |= 2u << base;
        } else if (sub == "range_sd_rel" && parse_doubles(val, v, 1) && v[0] >= 0.0) {
            fit->range_sd_rel = v[0];
            seen |= 4u << base;
        } else if (sub == "bearing_sd_deg" && parse_doubles(val, v, 1) && v[0] > 0.0) {
            fit->bearing_sd_rad = v[0] * 3.14159265358979 / 180.0;
            seen |= 8u << base;
        } else {
            bad = true;
            break;
        }
    }
    const bool err = std::ferror(f) != 0;
    std::fclose(f);
    if (err) return VISION_E_IO;
    if (bad || !format_ok || seen != 0xFFu) return VISION_E_FORMAT;
    if (out.landmark.range_sd_m <= 0.0 && out.landmark.range_sd_rel <= 0.0) return VISION_E_FORMAT;
    if (out.robot.range_sd_m <= 0.0 && out.robot.range_sd_rel <= 0.0) return VISION_E_FORMAT;
    *m = out;
    return VISION_OK;
}

vision_status_t vision_range_model_save(const vision_range_model_t *m, const char *path, const char *header)
{
    if (m == nullptr || path == nullptr) return VISION_E_ARG;
    FILE *f = std::fopen(path, "w");
    if (f == nullptr) return VISION_E_IO;
    if (header != nullptr) {
        std::string h(header);
        size_t pos = 0;
        while (pos < h.size()) {
            size_t nl = h.find('\n', pos);
            if (nl == std::string::npos) nl = h.size();
            std::fprintf(f, "# %s\n", h.substr(pos, nl - pos).c_str());
            pos = nl + 1;
        }
    }
    std::fprintf(f, "format = coslam-vision-range 1\n");
    const struct {
        const char *name;
        const vision_range_fit_t *fit;
    } kinds[2] = {{"landmark", &m->landmark}, {"robot", &m->robot}};
    for (const auto &k : kinds) {
        std::fprintf(f, "%s.c = %.9g %.9g %.9g\n", k.name, k.fit->c[0], k.fit->c[1], k.fit->c[2]);
        std::fprintf(f, "%s.range_sd_m = %.6g\n", k.name, k.fit->range_sd_m);
        std::fprintf(f, "%s.range_sd_rel = %.6g\n", k.name, k.fit->range_sd_rel);
        std::fprintf(f, "%s.bearing_sd_deg = %.6g\n", k.name, k.fit->bearing_sd_rad * 180.0 / 3.14159265358979);
    }
    return std::fclose(f) == 0 ? VISION_OK : VISION_E_IO;
}

}  // extern "C"
