; The I2C bench: the scratch ring's bus events, each timed in gpsim (chip_budget.i2c_event_cycles).
; The MSSP is set up as logger.asm sets it (I2C master, SSPADD = 10 at 18.432 MHz), the macros are step_record.asm's (i2c.inc) and
; i2c_tx is its routine, instruction for instruction: a random read's opening (start, control, address, restart,
; control), two bytes received and acknowledged as scr_next receives them, the last byte not acknowledged and
; the stop, as scr_close. A write of MARK (d'1', d'2', ...) follows each event; gpsim logs its cycle.
        list    p=16f877
        #include <p16f877.inc>
        __config _HS_OSC & _WDT_OFF & _LVP_OFF
MARK    equ     0x20
TMP0    equ     0x21
        #include "i2c.inc"
MARKW   macro   k
        movlw   k
        movwf   MARK
        endm
        org     0
        I2C_MASTER
        MARKW   d'1'
        I2C_CMD SEN
        MARKW   d'2'
        movlw   0xA0
        call    i2c_tx
        MARKW   d'3'
        movlw   0x00
        call    i2c_tx
        MARKW   d'4'
        movlw   0x00
        call    i2c_tx
        MARKW   d'5'
        I2C_CMD RSEN
        MARKW   d'6'
        movlw   0xA1
        call    i2c_tx
        MARKW   d'7'
        I2C_CMD RCEN
        movf    SSPBUF, W
        movwf   TMP0
        MARKW   d'8'
        I2C_ACK 0
        MARKW   d'9'
        I2C_CMD RCEN
        movf    SSPBUF, W
        movwf   TMP0
        MARKW   d'10'
        I2C_ACK 0
        MARKW   d'11'
        I2C_CMD RCEN
        MARKW   d'12'
        I2C_ACK 1
        MARKW   d'13'
        I2C_CMD PEN
        MARKW   d'14'
done:   goto    done
i2c_tx:
        bcf     STATUS, RP0
        bcf     STATUS, RP1
        movwf   SSPBUF
        I2C_WAIT
        return
        end
