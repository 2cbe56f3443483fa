/// @file md_controller.c
/// The controller object: node + cycles. See md_controller.h.
#include "md_controller.h"

#include <stddef.h>
#include <string.h>

md_controller_t *md_controller_instance(void)
{
    static md_controller_t instance; /* the controller's whole state: static, no heap */
    return &instance;
}

md_status_t md_controller_init(md_controller_t *c, const md_port_t *port, uint64_t now_us)
{
    if (c == NULL) {
        return MD_E_ARG;
    }
    const md_status_t st = md_node_init(&c->node, port, now_us);
    if (st != MD_OK) {
        return st;
    }
    return md_cycle_init(&c->cycle, &c->node);
}

void md_controller_on_frame(md_controller_t *c, const md_frame_t *f, uint64_t now_us)
{
    if (c == NULL || f == NULL) {
        return;
    }
    /* The node validates first (rejections are counted there); the cycle
     * acts only on accepted frames, and learns of rejected stream frames. */
    const bool accepted = md_node_on_frame(&c->node, f, now_us) == MD_OK;
    md_cycle_on_frame(&c->cycle, &c->node, f, accepted, now_us);
}

void md_controller_poll(md_controller_t *c, uint64_t now_us)
{
    if (c == NULL) {
        return;
    }
    (void)md_node_poll(&c->node, now_us); /* failures are counted by the node */
    md_cycle_poll(&c->cycle, &c->node, now_us);
}

uint64_t md_controller_next_deadline_us(const md_controller_t *c)
{
    if (c == NULL) {
        return 0u;
    }
    const uint64_t node_d = md_node_next_deadline_us(&c->node, 0u); /* 0 when it has work now */
    const uint64_t cycle_d = md_cycle_next_deadline_us(&c->cycle, &c->node);
    return (node_d < cycle_d) ? node_d : cycle_d;
}

md_node_t *md_controller_node(md_controller_t *c)
{
    return (c == NULL) ? NULL : &c->node;
}
