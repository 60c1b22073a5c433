/* The link backend of coslam-robot (robot_link.h). */
#include "robot_link.h"

hal_link_t *robot_open_link(const robot_config_t *cfg, const char **what)
{
    (void)cfg;
    /* ---- LINK BACKEND CHOICE ------------------------------------------------
     * Plug the Cyclone DDS link (hal/linux/dds) wrapped in the authentication
     * decorator (hal/linux/auth) in here: open it on cfg->link_domain with
     * cfg->link_peers and the fleet key read from cfg->fleet_key_file, and
     * fall back to the null link (with a reason in *what) if it cannot open.
     * Until then every robot maps alone. */
    if (what != NULL) {
        *what = "null (no DDS link in this build: no map exchange)";
    }
    return hal_link_null();
}

void robot_close_link(hal_link_t *link)
{
    hal_link_close(link);
}
