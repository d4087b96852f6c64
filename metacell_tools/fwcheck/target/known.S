/* Functions of known instruction count, to verify the QEMU instruction counter. */
    .syntax unified
    .cpu cortex-m0plus
    .thumb
    .text

/* 16 adds + bx lr = exactly 17 instructions */
    .global known_seq17
    .type known_seq17, %function
    .thumb_func
known_seq17:
    .rept 16
    adds r0, #1
    .endr
    bx lr
    .size known_seq17, . - known_seq17

/* known_loop(n), n >= 1: 1 + 3n + 1 = 3n + 2 instructions */
    .global known_loop
    .type known_loop, %function
    .thumb_func
known_loop:
    movs r1, #0
1:  adds r1, #1
    cmp r1, r0
    bne 1b
    bx lr
    .size known_loop, . - known_loop
