/* Build-time configuration of the cell program: identity, tick rate, PWM, pins. */
#ifndef CELL_CONFIG_H
#define CELL_CONFIG_H

/*
 * Identity. metacell_tools/flash builds one image per cell and passes both values
 * (PLATFORMIO_BUILD_SRC_FLAGS="-DMC_CELL_INDEX=j -DMC_CELL_ADDR=0x..."); the
 * cell -> address mapping itself lives only in metacell_tools/flash/addresses.py.
 * A plain `pio run -e cell` gives an unaddressed image (cell 0: the I2C hooks
 * are not started, the identity line says addr=none).
 */
#ifndef MC_CELL_INDEX
#define MC_CELL_INDEX 0
#endif
#ifndef MC_CELL_ADDR
#define MC_CELL_ADDR 0
#endif
#if MC_CELL_INDEX == 0
#if MC_CELL_ADDR != 0
#error "MC_CELL_ADDR given without MC_CELL_INDEX"
#endif
#elif MC_CELL_INDEX < 1 || MC_CELL_INDEX > 64   /* MC_MAX_CELLS: a sheet of up to 64 cells (protocol/definition.py) */
#error "MC_CELL_INDEX must be 1..64"
#elif MC_CELL_ADDR < 0x08 || MC_CELL_ADDR > 0x77
#error "MC_CELL_ADDR must be a non-reserved 7-bit I2C address (0x08..0x77)"
#endif

/* Control tick rate in Hz (TC3). The library accepts 100..50000. */
#ifndef MC_CTRL_RATE_HZ
#define MC_CTRL_RATE_HZ 2000
#endif
#if MC_CTRL_RATE_HZ < 100 || MC_CTRL_RATE_HZ > 50000
#error "MC_CTRL_RATE_HZ must be 100..50000"
#endif

/* PWM period in 48 MHz TCC0 ticks: 2400 = 20 kHz, ~11.2 bits. Library: 255..4095. */
#ifndef MC_PWM_TOP
#define MC_PWM_TOP 2400
#endif
#if MC_PWM_TOP < 255 || MC_PWM_TOP > 4095
#error "MC_PWM_TOP must be 255..4095"
#endif

/* 1: enable the drive at power-up (stand-alone rig without a primary).
 * 0 (default): the drive stays off until the bus (docs/datapath.md) enables it. */
#ifndef MC_ENABLE_AT_BOOT
#define MC_ENABLE_AT_BOOT 0
#endif

/* Arduino pin numbers of the XIAO (docs/physics.md#actuators, docs/hardware.md; see docs/hardware.md). */
#define CELL_PIN_NSLEEP 0     /* D0 = PA02: nSLEEP of both DRV8874 (our choice) */
#define CELL_PIN_DIR_A 1      /* D1 = PA04: PH of the alpha driver */
#define CELL_PIN_PWM_A 2      /* D2 = PA10: EN of the alpha driver, TCC0/WO[2] */
#define CELL_PIN_PWM_B 3      /* D3 = PA11: EN of the beta driver,  TCC0/WO[3] */
#define CELL_PIN_SDA 4        /* D4 = PA08 (SERCOM2, used by the bus glue) */
#define CELL_PIN_SCL 5        /* D5 = PA09 */
#define CELL_PIN_DIR_B 6      /* D6 = PB08: PH of the beta driver */
#define CELL_PIN_ENC_A_A 7    /* D7 = PB09: alpha encoder channel A */
#define CELL_PIN_ENC_A_B 8    /* D8 = PA07: alpha encoder channel B */
#define CELL_PIN_ENC_B_A 9    /* D9 = PA05: beta encoder channel A */
#define CELL_PIN_ENC_B_B 10   /* D10 = PA06: beta encoder channel B */
/* nFAULT: every XIAO header pin is taken, so it is not wired by default. Define
 * MC_PIN_NFAULT to an Arduino pin number if your build frees one (open-drain,
 * both drivers' nFAULT tied together, pulled up to 3.3 V). */
#ifndef MC_PIN_NFAULT
#define MC_PIN_NFAULT (-1)
#endif

#endif /* CELL_CONFIG_H */
