; Test bench for the kernels in gpsim: one loop per kernel, selected by KERNEL_SELECT at reset.
; gpsim stops at the loop's label (at_<kernel>) before every call; the harness script writes the
; operands into the maths registers, runs, and reads the results and the cycle counter at the next stop.
; Cycles between two stops = CALL + kernel + RETURN + the loop's GOTO (2).
        list    p=16f877
        #include <p16f877.inc>
        #include "registers.inc"
        __CONFIG _HS_OSC & _WDT_OFF & _PWRTE_ON & _LVP_OFF & _BODEN_OFF & _CP_OFF


        cblock  0x20
        KERNEL_SELECT           ; which kernel loop to enter, written by the script before the first run
        STARTS                  ; incremented at every (re)start: the script checks it is 1 at the end
        endc

        org     0
        goto    start

        org     0x10
start:
        incf    STARTS, F
        clrf    FLAGS
        movlw   HIGH dispatch
        movwf   PCLATH
        movf    KERNEL_SELECT, W
        addwf   PCL, F
dispatch:
        goto    at_mul16u       ; 0
        goto    at_mul16s       ; 1
        goto    at_div32u       ; 2
        goto    at_div32s       ; 3
        goto    at_divr32u      ; 4
        goto    at_divr32s      ; 5
        goto    at_shr32        ; 6
        goto    at_shr32r       ; 7
        goto    at_sat16        ; 8
        goto    at_isqrt32      ; 9
        goto    at_isqrt32n     ; 10
        goto    at_iroot4       ; 11

at_mul16u:
        call    mul16u
        goto    at_mul16u
at_mul16s:
        call    mul16s
        goto    at_mul16s
at_div32u:
        call    div32u
        goto    at_div32u
at_div32s:
        call    div32s
        goto    at_div32s
at_divr32u:
        call    divr32u
        goto    at_divr32u
at_divr32s:
        call    divr32s
        goto    at_divr32s
at_shr32:
        call    shr32
        goto    at_shr32
at_shr32r:
        call    shr32r
        goto    at_shr32r
at_sat16:
        call    sat16
        goto    at_sat16
at_isqrt32:
        call    isqrt32
        goto    at_isqrt32
at_isqrt32n:
        call    isqrt32n
        goto    at_isqrt32n
at_iroot4:
        call    iroot4
        goto    at_iroot4

kernels_begin:                  ; program words of the kernels: kernels_end - kernels_begin
        #include "mul.asm"
        #include "div.asm"
        #include "shift.asm"
        #include "sat.asm"
        #include "sqrt.asm"
kernels_end:

        end
