; The journal bench: journal.asm's journal_write run in gpsim on one entry (gpsim_journal.py). The MSSP is set up
; as logger.asm sets it (I2C master, SSPADD = 10 at 18.432 MHz), the macros are i2c.inc's. The entry's inputs
; come in as assembler symbols (E_M commit, E_S steps, E_R recording_number, E_N recording_nonce, 32 bits each);
; a write of MARK (1, 2, 3) brackets journal_write, whose cycles gpsim's log stamps. Then the bench reads the 16
; bytes at E_ADDR (the Python model's ring_address, bit 15 dropped: gpsim's 24xx256 has 32 KiB) back from the
; EEPROM into BACK (a random read, as step_record.asm's reader does it), where the log shows them.
        list    p=16f877
        #include <p16f877.inc>
        __config _HS_OSC & _WDT_OFF & _LVP_OFF
        #include "registers.inc"
MARK    equ     0x20
JE_RAM  equ     0x21                    ; 16 bytes: the entry's inputs
BACK    equ     0x31                    ; 16 bytes read back
        #include "i2c.inc"
MARKW   macro   k
        movlw   k
        movwf   MARK
        endm
LOAD32  macro   dst, value
        movlw   (value) & 0xFF
        movwf   dst
        movlw   ((value) >> 8) & 0xFF
        movwf   dst + 1
        movlw   ((value) >> .16) & 0xFF
        movwf   dst + 2
        movlw   ((value) >> .24) & 0xFF
        movwf   dst + 3
        endm
        org     0
        I2C_MASTER
        LOAD32  JE_RAM, E_M
        LOAD32  JE_RAM + 4, E_S
        LOAD32  JE_RAM + 8, E_R
        LOAD32  JE_RAM + .12, E_N
        MARKW   d'1'
        call    journal_write
        MARKW   d'2'
        I2C_CMD SEN                     ; read back: start, control, address, restart, control (read)
        movlw   0xA0
        call    jr_tx
        movlw   (E_ADDR >> 8) & 0x7F
        call    jr_tx
        movlw   E_ADDR & 0xFF
        call    jr_tx
        I2C_CMD RSEN
        movlw   0xA1
        call    jr_tx
        movlw   BACK
        movwf   FSR
        bcf     STATUS, IRP
        movlw   .16
        movwf   COUNT
back_next:
        I2C_CMD RCEN
        movf    SSPBUF, W
        movwf   INDF
        incf    FSR, F
        decf    COUNT, F
        btfsc   STATUS, Z
        goto    back_last
        I2C_ACK 0
        goto    back_next
back_last:
        I2C_ACK 1
        I2C_CMD PEN
        MARKW   d'3'
done:   goto    done
        #include "journal.asm"
        end
