/// @file md_can_uart.h
/// The CAN FD controller of the QEMU board: QEMU's mps2-an500 has none, so
/// the frames travel over the board's CMSDK APB UARTs (QEMU `-serial`), one
/// md_link packet per frame (SLIP + CRC-16, common/link/md_link.h), to a host
/// bridge (`mdcan bridge`) that puts them on a CAN bus, exactly as a
/// USB-to-CAN adapter would. This file pair is the one a real board replaces
/// with its CAN FD driver (same calls). docs/pil.md.
///
/// Host to board, the byte stream is striped over all five UARTs (byte k on
/// UART k mod 5): QEMU hands a UART one byte per main-loop pass, so five
/// carry about five times what one does. Board to host (telemetry, a few
/// hundred frames per cycle) uses UART0 alone.
///
/// Receive is interrupt-driven: each UART's RX interrupt moves its byte into
/// that UART's ring of MD_CAN_UART_RX_RING bytes; when a ring is full its
/// interrupt is switched off and the byte stays in the UART, so QEMU stops
/// delivering on it and the host side waits (no byte is ever dropped by the
/// guest). Transmit writes the encoded packet byte by byte to UART0, waiting
/// a bounded time for its holding register.
#ifndef MD_CAN_UART_H
#define MD_CAN_UART_H

#include <stdbool.h>
#include <stdint.h>

#include "md_status.h"
#include "md_frame.h"

/// UARTs the host-to-board stream is striped over (the AN500 has five).
#define MD_CAN_UART_STRIPES 5u
/// RX ring size per UART in bytes (a power of two): all five hold ~135
/// REC_DATA frames.
#define MD_CAN_UART_RX_RING 2048u

/// Counters of the link (every failure counted).
typedef struct {
    uint32_t tx_frames;     ///< frames written to the UART
    uint32_t tx_timeouts;   ///< frames abandoned: the UART stayed full (host not reading)
    uint32_t rx_frames;     ///< valid frames decoded
    uint32_t rx_bad_crc;    ///< packets dropped: CRC
    uint32_t rx_bad_frame;  ///< packets dropped: not a valid frame
    uint32_t rx_bad_esc;    ///< packets dropped: bad SLIP escape
    uint32_t rx_too_long;   ///< packets dropped: longer than any frame
    uint32_t rx_overruns;   ///< bytes the UART itself reported lost (STATE.RX overrun)
    uint32_t rx_ring_full;  ///< times the ring filled up and the RX interrupt paused
} md_can_uart_stats_t;

/// Sets up UART0 (enable, RX interrupt, NVIC line) and empties the decoder.
void md_can_uart_init(void);

/// Sends one frame (must be md_frame_valid). MD_E_ARG for an invalid frame,
/// MD_E_IO when the UART stayed full for MD_CAN_UART_TX_SPIN polls (counted).
md_status_t md_can_uart_send(const md_frame_t *f);

/// Decodes received bytes until a whole frame is in *out (true) or no byte
/// is left (false). Bounded by the ring's size.
bool md_can_uart_receive(md_frame_t *out);

/// True if the next byte of the stream waits in its ring (the main loop must
/// not sleep).
bool md_can_uart_rx_pending(void);

/// Holds back (hold = true) or lets run (false) the UART receive interrupts:
/// bytes arriving meanwhile wait in the UARTs (flow control), nothing is
/// lost. Around the controller's measured work (md_port_t work_section).
void md_can_uart_rx_hold(bool hold);

/// The link's counters.
const md_can_uart_stats_t *md_can_uart_stats(void);

/// SysTick ticks spent inside the UART interrupts since start (so that the
/// cost of the controller's work can leave the link's out).
uint64_t md_can_uart_isr_ticks(void);

/// RX interrupts of UART0..4 (external interrupts 0, 2, 4, 18, 20 on the AN500).
void UART0RX_IRQHandler(void);
void UART1RX_IRQHandler(void);
void UART2RX_IRQHandler(void);
void UART3RX_IRQHandler(void);
void UART4RX_IRQHandler(void);

#endif
