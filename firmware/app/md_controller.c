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
    memset(&c->cycle, 0, sizeof c->cycle);
    return md_node_init(&c->node, port, now_us);
}

void md_controller_on_frame(md_controller_t *c, const md_frame_t *f, uint64_t now_us)
{
    if (c == NULL || f == NULL) {
        return;
    }
    (void)md_node_on_frame(&c->node, f, now_us); /* rejections are counted by the node */
}

void md_controller_poll(md_controller_t *c, uint64_t now_us)
{
    if (c == NULL) {
        return;
    }
    (void)md_node_poll(&c->node, now_us); /* failures are counted by the node */
}

uint64_t md_controller_next_deadline_us(const md_controller_t *c)
{
    if (c == NULL) {
        return 0u;
    }
    const uint64_t d = md_node_next_deadline_us(&c->node, 0u);
    return d;
}

md_node_t *md_controller_node(md_controller_t *c) { return (c == NULL) ? NULL : &c->node; }
