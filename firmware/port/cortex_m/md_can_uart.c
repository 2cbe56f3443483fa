/* CAN FD frames over the CMSDK APB UART0 of QEMU's mps2-an500 (md_link
 * packets). The board-specific CAN driver of a real board replaces this file. */
#include "md_can_uart.h"

#include <stddef.h>

#include "md_link.h"
#include "md_port_m7.h"

/* CMSDK APB UART (ARM DDI 0479C, 4.3); the AN500's UART0..4 and their RX
 * interrupt lines (QEMU hw/arm/mps2.c). */
#define UART_DATA(b) (*(volatile uint32_t *)((b) + 0x00u))
#define UART_STATE(b) (*(volatile uint32_t *)((b) + 0x04u))
#define UART_CTRL(b) (*(volatile uint32_t *)((b) + 0x08u))
#define UART_INTCLEAR(b) (*(volatile uint32_t *)((b) + 0x0Cu))
#define UART_BAUDDIV(b) (*(volatile uint32_t *)((b) + 0x10u))
#define STATE_TXFULL (1u << 0)
#define STATE_RXFULL (1u << 1)
#define STATE_RX_OVERRUN (1u << 3)
#define CTRL_TX_EN (1u << 0)
#define CTRL_RX_EN (1u << 1)
#define CTRL_RX_INT_EN (1u << 3)
#define INT_RX (1u << 1)
/* 115 200 baud from the 25 MHz clock on silicon; QEMU does not time the line. */
#define UART_BAUDDIV_VALUE (MD_M7_SYSCLK_HZ / 115200u)
_Static_assert(UART_BAUDDIV_VALUE >= 16u, "CMSDK UART: BAUDDIV must be at least 16");

static const uint32_t uart_base[MD_CAN_UART_STRIPES] = {0x40004000u, 0x40005000u, 0x40006000u, 0x40007000u,
                                                        0x40009000u};
static const uint32_t uart_rx_irq[MD_CAN_UART_STRIPES] = {0u, 2u, 4u, 18u, 20u};
_Static_assert(MD_CAN_UART_STRIPES == 5u, "the tables above list the AN500's five UARTs");

/* NVIC (ARMv7-M ARM, B3.4). */
#define NVIC_ISER0 (*(volatile uint32_t *)0xE000E100u)
#define NVIC_ICER0 (*(volatile uint32_t *)0xE000E180u)
#define UART_RX_IRQ_MASK ((1u << 0) | (1u << 2) | (1u << 4) | (1u << 18) | (1u << 20))

/* Polls of TXFULL per byte before a frame is abandoned (tens of ms of
 * virtual time: far beyond the host bridge's latency). */
#define MD_CAN_UART_TX_SPIN 2000000u

#define RING_MASK (MD_CAN_UART_RX_RING - 1u)
_Static_assert((MD_CAN_UART_RX_RING & RING_MASK) == 0u, "ring size is a power of two");
#define RING_BYTES_ALL (MD_CAN_UART_RX_RING * MD_CAN_UART_STRIPES)
_Static_assert(RING_BYTES_ALL >= 2u * MD_LINK_ENCODED_MAX, "the rings hold at least two frames");

/* One RX ring per UART. head: written by that UART's interrupt only; tail:
 * by the main loop only. */
typedef struct {
    uint8_t buf[MD_CAN_UART_RX_RING];
    volatile uint32_t head;
    volatile uint32_t tail;
} rx_ring_t;

static rx_ring_t rx_ring[MD_CAN_UART_STRIPES];
static uint32_t rx_next; /* the stripe that holds the next byte of the stream */
static volatile uint64_t isr_ticks;
static volatile uint32_t rx_overruns;
static volatile uint32_t rx_ring_full;
static md_link_decoder_t decoder;
static md_can_uart_stats_t stats;

/* Both are called from thread code only, where interrupts are enabled. */
static inline void irq_off(void)
{
    __asm__ volatile("cpsid i" ::: "memory");
}
static inline void irq_on(void)
{
    __asm__ volatile("cpsie i" ::: "memory");
}

void md_can_uart_init(void)
{
    rx_next = 0u;
    isr_ticks = 0u;
    rx_overruns = 0u;
    rx_ring_full = 0u;
    md_link_decoder_init(&decoder);
    stats = (md_can_uart_stats_t){0};
    for (uint32_t j = 0u; j < MD_CAN_UART_STRIPES; ++j) {
        const uint32_t b = uart_base[j];
        UART_CTRL(b) = 0u;
        rx_ring[j].head = 0u;
        rx_ring[j].tail = 0u;
        UART_BAUDDIV(b) = UART_BAUDDIV_VALUE;
        UART_INTCLEAR(b) = 0xFu;
        UART_CTRL(b) = CTRL_TX_EN | CTRL_RX_EN | CTRL_RX_INT_EN;
        NVIC_ISER0 = 1u << uart_rx_irq[j];
    }
}

void md_can_uart_rx_hold(bool hold)
{
    if (hold) {
        NVIC_ICER0 = UART_RX_IRQ_MASK;
        __asm__ volatile("dsb\n isb" ::: "memory");
    } else {
        NVIC_ISER0 = UART_RX_IRQ_MASK;
    }
}

/* The RX interrupt of stripe j. */
static void rx_isr(uint32_t j)
{
    const uint64_t t0 = md_port_m7_ticks();
    const uint32_t b = uart_base[j];
    rx_ring_t *const r = &rx_ring[j];
    UART_INTCLEAR(b) = INT_RX;
    if ((UART_STATE(b) & STATE_RX_OVERRUN) != 0u) {
        UART_STATE(b) = STATE_RX_OVERRUN; /* write 1 to clear */
        rx_overruns = rx_overruns + 1u;
    }
    /* One byte is all the CMSDK UART holds; QEMU delivers the next one after
     * this read. A full ring leaves the byte in the UART and pauses the
     * interrupt: md_can_uart_receive takes it and resumes. */
    if ((UART_STATE(b) & STATE_RXFULL) != 0u) {
        const uint32_t head = r->head;
        if (head - r->tail >= MD_CAN_UART_RX_RING) {
            UART_CTRL(b) = CTRL_TX_EN | CTRL_RX_EN;
            rx_ring_full = rx_ring_full + 1u;
        } else {
            r->buf[head & RING_MASK] = (uint8_t)UART_DATA(b);
            r->head = head + 1u;
        }
    }
    isr_ticks = isr_ticks + (md_port_m7_ticks() - t0);
}

void UART0RX_IRQHandler(void)
{
    rx_isr(0u);
}
void UART1RX_IRQHandler(void)
{
    rx_isr(1u);
}
void UART2RX_IRQHandler(void)
{
    rx_isr(2u);
}
void UART3RX_IRQHandler(void)
{
    rx_isr(3u);
}
void UART4RX_IRQHandler(void)
{
    rx_isr(4u);
}

/* Stripe j's interrupt is paused (its ring was full): once the ring has room
 * again, let the interrupt run and take the byte the UART held meanwhile.
 * With interrupts masked, in this order: a byte arriving after the enable
 * raises the interrupt; the one held before it (QEMU flags a received byte
 * only while the interrupt is enabled) is read here. */
static void resume_rx(uint32_t j)
{
    const uint32_t b = uart_base[j];
    rx_ring_t *const r = &rx_ring[j];
    if ((UART_CTRL(b) & CTRL_RX_INT_EN) != 0u || r->head - r->tail >= MD_CAN_UART_RX_RING) {
        return; /* running, or still no room */
    }
    irq_off();
    UART_CTRL(b) = CTRL_TX_EN | CTRL_RX_EN | CTRL_RX_INT_EN;
    if ((UART_STATE(b) & STATE_RXFULL) != 0u) {
        r->buf[r->head & RING_MASK] = (uint8_t)UART_DATA(b);
        r->head = r->head + 1u;
    }
    irq_on();
}

bool md_can_uart_receive(md_frame_t *out)
{
    if (out == NULL) {
        return false;
    }
    bool got = false;
    /* byte k of the stream is on stripe k mod MD_CAN_UART_STRIPES */
    for (uint32_t k = 0u; k < MD_CAN_UART_RX_RING * MD_CAN_UART_STRIPES && !got; ++k) {
        rx_ring_t *const r = &rx_ring[rx_next];
        const uint32_t tail = r->tail;
        if (tail == r->head) {
            break;
        }
        const uint8_t byte = r->buf[tail & RING_MASK];
        r->tail = tail + 1u;
        rx_next = (rx_next + 1u) % MD_CAN_UART_STRIPES;
        got = md_link_decode_byte(&decoder, byte, out) == MD_LINK_FRAME;
    }
    for (uint32_t j = 0u; j < MD_CAN_UART_STRIPES; ++j) {
        resume_rx(j);
    }
    return got;
}

bool md_can_uart_rx_pending(void)
{
    const rx_ring_t *const r = &rx_ring[rx_next];
    return r->head != r->tail;
}

md_status_t md_can_uart_send(const md_frame_t *f)
{
    uint8_t buf[MD_LINK_ENCODED_MAX];
    const size_t n = md_link_encode(f, buf, sizeof buf);
    if (n == 0u) {
        return MD_E_ARG;
    }
    for (size_t i = 0u; i < n; ++i) {
        uint32_t spin = 0u;
        while ((UART_STATE(uart_base[0]) & STATE_TXFULL) != 0u && spin < MD_CAN_UART_TX_SPIN) {
            spin++;
        }
        if (spin >= MD_CAN_UART_TX_SPIN) {
            stats.tx_timeouts++;
            return MD_E_IO; /* the receiver resynchronises at the next END */
        }
        UART_DATA(uart_base[0]) = buf[i];
    }
    stats.tx_frames++;
    return MD_OK;
}

const md_can_uart_stats_t *md_can_uart_stats(void)
{
    stats.rx_frames = decoder.frames;
    stats.rx_bad_crc = decoder.bad_crc;
    stats.rx_bad_frame = decoder.bad_frame;
    stats.rx_bad_esc = decoder.bad_esc;
    stats.rx_too_long = decoder.too_long;
    stats.rx_overruns = rx_overruns;
    stats.rx_ring_full = rx_ring_full;
    return &stats;
}

uint64_t md_can_uart_isr_ticks(void)
{
    irq_off();
    const uint64_t t = isr_ticks;
    irq_on();
    return t;
}
