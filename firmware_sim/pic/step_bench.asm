; Test bench of the step record (step_record.asm) in gpsim: one run per segment of a recording's steps.
; gpsim_steps.py writes the tables and assembles with (gpasm -D):
;   N_STEPS         steps in the step table
;   SCR_J0          the sample index of the scratch table's first sample
;   TABLE_READER    (optional) the scratch ring's test-build reader: a table in program memory, not the I2C bus
;   SCR_SAMPLES, SCR_K0 (without TABLE_READER) the scratch ring's samples and its offset K (logger.asm)
; and the includes: steps.inc (STEP_TABLE: per step 12 words, the low byte of each: e, m, LAST, the
; algorithm's FLAGS, the sticky saturation flag, the absolute sample number of m (4 bytes, LE)),
; scratch.inc (SCR_TABLE: a_v, two words a sample; TABLE_READER only) and config.inc (the data EEPROM: the
; step configuration). Without TABLE_READER the ring is a 24xx256 on the MSSP's I2C bus (RC3 SCL, RC4 SDA), that
; gpsim's e24xx256 module models and the gpsim script fills before the run.
; Per step the bench loads the inputs, stamps MARK, calls finalise from four stack levels deep (so a
; finalise deeper than 4 levels overflows the PIC's 8-level stack: gpsim reports it), stamps MARK again and
; writes the record's 20 bytes, then ALG_FLAGS, ALG_LAST_L/H and the kernels' FLAGS, to OUTB. gpsim's
; register-write log collects them; nothing stops the simulation before bench_done.
        list    p=16f877
        #include <p16f877.inc>
        #include "registers.inc"
; The logger's RAM map sized as at 50 Hz (steps 4-5's delay line and durations ring): the bench uses only the
; algorithm state finalise reads and updates (AFLAGS, LAST), as logger.asm does; finalise itself reads r3
; and its other counts from the data EEPROM.
R3              equ     .9
N_MED           equ     .7
        #include "logger_ram.inc"
ALG_FLAGS       equ     AFLAGS
ALG_LAST_L      equ     LAST
ALG_LAST_H      equ     LAST + 1
        #include "step_record_ram.inc"
        __CONFIG _HS_OSC & _WDT_OFF & _PWRTE_ON & _LVP_OFF & _BODEN_OFF & _CP_OFF

BENCH_CODE      equ     0x0800          ; the bench in page 1: page 0 holds finalise and the kernels
STEP_TABLE      equ     0x0A00
#ifdef TABLE_READER
SCR_TABLE       equ     0x1000
#endif
STEP_WORDS      equ     .12

MARK            equ     0x7F            ; common RAM (the logger's W_TEMP: no interrupts here)
        cblock  STATUS_TEMP             ; bank 0: the interrupt's 5 bytes (no interrupts here)
        OUTB                            ; the bench's output byte (logged)
        LEFT_L, LEFT_H                  ; steps still to run
        TBL_L, TBL_H                    ; program-memory address of the next table word
        endc

        org     0
        pagesel start
        goto    start
        org     4
        pagesel start
        goto    start

step_code_begin:                        ; program words of finalise and its helpers: step_code_end - begin
        #include "step_record.asm"
step_code_end:
kernels_begin:
        #include "mul.asm"
        #include "div.asm"
        #include "shift.asm"
        #include "sat.asm"
        #include "sqrt.asm"
kernels_end:

        org     BENCH_CODE
start:
        clrf    STATUS
        clrf    FLAGS
#ifndef TABLE_READER
        banksel TRISC                   ; the MSSP: I2C master, 419 kHz (SSPADD = 10 at 18.432 MHz)
        bsf     TRISC, 3
        bsf     TRISC, 4
        movlw   .10
        movwf   SSPADD
        clrf    SSPSTAT
        banksel SSPCON
        movlw   0x28
        movwf   SSPCON
        banksel SCR_K_L                 ; the scratch ring's offset (logger_ram.inc SCR_K): the segment's
        movlw   LOW SCR_K0              ; samples are where the logger's scr_write put them
        movwf   SCR_K_L
        movlw   HIGH SCR_K0
        movwf   SCR_K_H
#endif
        banksel LEFT_L
        movlw   LOW N_STEPS
        movwf   LEFT_L
        movlw   HIGH N_STEPS
        movwf   LEFT_H
        movlw   LOW STEP_TABLE
        movwf   TBL_L
        movlw   HIGH STEP_TABLE
        movwf   TBL_H
step_next:
        call    tbl_byte
        banksel E_L
        movwf   E_L
        call    tbl_byte
        banksel E_H
        movwf   E_H
        call    tbl_byte
        banksel FM_L
        movwf   FM_L
        call    tbl_byte
        banksel FM_H
        movwf   FM_H
        call    tbl_byte
        banksel ALG_LAST_L
        movwf   ALG_LAST_L
        call    tbl_byte
        banksel ALG_LAST_H
        movwf   ALG_LAST_H
        call    tbl_byte
        banksel ALG_FLAGS
        movwf   ALG_FLAGS
        call    tbl_byte
        bcf     FLAGS, FLAG_SAT
        andlw   1
        btfss   STATUS, Z
        bsf     FLAGS, FLAG_SAT
        call    tbl_byte
        banksel REC
        movwf   REC
        call    tbl_byte
        banksel REC
        movwf   REC+1
        call    tbl_byte
        banksel REC
        movwf   REC+2
        call    tbl_byte
        banksel REC
        movwf   REC+3
        call    level1
        ; the outputs
        movlw   LOW REC
        movwf   FSR
        bsf     STATUS, IRP
        movlw   .20
        movwf   COUNT
out_rec:
        movf    INDF, W
        banksel OUTB
        movwf   OUTB
        incf    FSR, F
        decfsz  COUNT, F
        goto    out_rec
        banksel ALG_FLAGS               ; the state (bank 1) to OUTB (bank 0)
        movf    ALG_FLAGS, W
        banksel OUTB
        movwf   OUTB
        banksel ALG_LAST_L
        movf    ALG_LAST_L, W
        banksel OUTB
        movwf   OUTB
        banksel ALG_LAST_H
        movf    ALG_LAST_H, W
        banksel OUTB
        movwf   OUTB
        movf    FLAGS, W
        movwf   OUTB
        banksel LEFT_L
        movlw   1
        subwf   LEFT_L, F
        btfss   STATUS, C
        decf    LEFT_H, F
        movf    LEFT_L, W
        iorwf   LEFT_H, W
        btfss   STATUS, Z
        goto    step_next
bench_done:
        goto    bench_done

level1:
        call    level2
        return
level2:
        call    level3
        return
level3:
        call    level4
        return
level4:
        pagesel finalise
        bcf     STATUS, RP0             ; bank 0: both stamps write 0x7F itself
        bcf     STATUS, RP1
        movwf   MARK                    ; cycle stamp: finalise's CALL follows
        call    finalise
        movwf   MARK                    ; cycle stamp: 1 cycle after finalise's RETURN
        pagesel $
        return

; tbl_byte: W = the low byte of the table word at TBL; TBL advances.
tbl_byte:
        banksel TBL_L
        movf    TBL_L, W
        banksel EEADR
        movwf   EEADR
        banksel TBL_H
        movf    TBL_H, W
        banksel EEADRH
        movwf   EEADRH
        banksel EECON1
        bsf     EECON1, EEPGD
        bsf     EECON1, RD
        nop
        nop
        banksel TBL_L
        incf    TBL_L, F
        btfsc   STATUS, Z
        incf    TBL_H, F
        banksel EEDATA
        movf    EEDATA, W
        bcf     STATUS, RP0
        bcf     STATUS, RP1
        return

        org     STEP_TABLE
        #include "steps.inc"
#ifdef TABLE_READER
        org     SCR_TABLE
        #include "scratch.inc"
#endif
        #include "config.inc"

        end
