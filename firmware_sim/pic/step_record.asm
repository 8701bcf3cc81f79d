; Step 6 of the on-line step algorithm: the step record at a final foot-flat (kernel.py's _finalise), bit
; for bit. RAM and configuration map: step_record_ram.inc. Maths: the kernels (registers.inc, CONVENTION.md).
;
; finalise
;   in:  E_L/E_H = e (the final foot-flat), FM_L/FM_H = m (the newest filter output), REC+0..3 = the absolute
;        sample number of m (32-bit), ALG_FLAGS / ALG_LAST_L/H = the algorithm's FLAGS and LAST (state.py),
;        FLAGS bit FLAG_SAT = the sticky saturation flag since the last step;
;        the step configuration in the data EEPROM (STEP_CFG_EE, step_record_ram.inc's CFG_*);
;        a_v on the scratch ring, read through scr_open / scr_next (below).
;   out: REC = the 20-byte record as protocol/steps.py packs it (CRC-16/XMODEM big-endian in bytes 18-19);
;        ALG_LAST = e, ALG_FLAGS: F_LAST set, F_LAST_WEAK = F_PEND_WEAK, F_PEND_WEAK cleared; FLAG_SAT cleared.
;   clobbers: the kernels' registers, FSR, IRP, EEADR(H), W, STATUS; returns in bank 0.
;   stack: 4 levels, finalise's own return address included (e.g. finalise -> fir_eval -> fir_tap ->
;   ee_cfg; fir_tap tail-calls mul16s -> mul16u; finalise -> isqrt32n -> isqrt32 -> sq_shift2).
;
; The parts, in this order (the kernel's order differs; each part keeps only its own accumulators, the
; sticky flag is an OR over all of them, so the order does not change the record):
;   1. end_sample = (sample number of m) - since(m, e);
;   2. the heel strike: the first maximum of the band d10 - d5 in [e - hs_before, e + min(hs_after, m - e)]
;      (lo at r3 while the run is young), minus hs_delay;
;   3. the window: NO_WINDOW when F_LAST is clear or e - s > max_step; otherwise
;   4. the toe-off (first local minimum of d10 in (s, s + min(to_span, m - s - 1)]) and the events' checks;
;   5. M4: the range of y3 over [s, e], K4 (range)^p, p = eighths / 8 (configuration byte: 4 = 1/2, 2 = 1/4);
;   6. pass 1 over a_v[s..e]: V, P, P's extremes; c1 = -V / 2T, c2 = (16 P + 2 c1 T^2) / T; M1;
;   7. pass 2: M2's p2 by increments, its extremes and those of the single support; M2, M3;
;   8. M5 = K1 fs / T + K2; the flags, the CRC; the state.
; Every FIR window is read from the ring once (2R + 1 samples) and its pairs a[c-t] + a[c+t] are formed once
; (saturated as the kernel's); the heel strike's d10 and d5 share one window of radius max(r10, r5).

; ---- macros ---------------------------------------------------------------------------------------------
B2      macro                           ; bank 2 (RP1 is 1 throughout finalise)
        bcf     STATUS, RP0
        endm
B3      macro                           ; bank 3
        bsf     STATUS, RP0
        endm
PTR     macro   addr                    ; FSR and IRP -> addr
        movlw   LOW (addr)
        movwf   FSR
        if ((addr) & 0x100)
        bsf     STATUS, IRP
        else
        bcf     STATUS, IRP
        endif
        endm
CFGW    macro   off                     ; W = configuration byte off (leaves bank 2)
        movlw   off
        call    ee_cfg
        endm
CP16    macro   dst, src                ; two bytes, same bank
        movf    src, W
        movwf   dst
        movf    src+1, W
        movwf   dst+1
        endm

D10_AT  macro                           ; ACC = the 10 Hz FIR at sample ARG1:ARG0 (Q2.16, sign-extended)
        CFGW    CFG_R10
        call    fir_load
        CFGW    CFG_R10
        movwf   FIR_T
        CFGW    CFG_W10_AT
        call    fir_eval
        endm
Y3_AT   macro                           ; ACC = the 3 Hz FIR at sample ARG1:ARG0
        CFGW    CFG_R3
        call    fir_load
        CFGW    CFG_R3
        movwf   FIR_T
        movlw   CFG_W3
        call    fir_eval
        endm
M4ROOT  macro                           ; FACC = the nearest square root of FACC << 15 (UQ1.15 -> UQ1.15)
        movlw   LOW FACC
        call    ld32_w
        movlw   F_ROOT_BITS
        call    shl_u32
        call    isqrt32n
        movlw   LOW FACC
        call    st32_w
        endm

; Q formats the code is written for (formats.py; tests/firmware_sim/test_pic_step_record.py checks them)
F_ACC_BITS      equ     .13             ; a_v, Q2.13
F_LP_BITS       equ     .16             ; FIR outputs, Q2.16 in 19 bits
F_FIR_BITS      equ     .27             ; FIR sums, Q4.27
F_POS2_BITS     equ     .17             ; M2's position
F_EXC_BITS      equ     .16             ; M1's excursion, UQ0.16
F_EXC2_BITS     equ     .18             ; M2/M3's excursion, UQ-2.18
F_TWO_LEN_BITS  equ     .14             ; 2 l, UQ2.14
F_STEP_BITS     equ     .14             ; step lengths, UQ2.14
F_K_BITS        equ     .15             ; K, UQ1.15
F_K4_BITS       equ     .14             ; K4, UQ2.14
F_ROOT_BITS     equ     .15             ; M4's roots, UQ1.15
F_M5_BITS       equ     .16             ; M5's constants, Q15.16

; ==========================================================================================================
finalise:
        bsf     STATUS, RP1
        B3
        bsf     STATUS, IRP
        clrf    FIN_F
        PTR     REC+4                   ; duration .. lengths = 0
        movlw   .14
        movwf   COUNT
fin_clear:
        clrf    INDF
        incf    FSR, F
        decfsz  COUNT, F
        goto    fin_clear
        ; 1. end_sample = REC+0..3 - (m - e)
        movf    E_L, W
        subwf   FM_L, W
        movwf   TMP0
        movf    E_H, W
        btfss   STATUS, C
        incf    E_H, W
        subwf   FM_H, W
        movwf   TMP1                    ; TMP1:TMP0 = since(m, e) >= 0
        movf    TMP0, W
        subwf   REC+0, F
        movf    TMP1, W
        btfss   STATUS, C
        incfsz  TMP1, W
        subwf   REC+1, F
        btfsc   STATUS, C
        goto    fin_young
        movlw   1
        subwf   REC+2, F
        btfss   STATUS, C
        decf    REC+3, F
fin_young:
        banksel ALG_FLAGS
        movf    ALG_FLAGS, W
        bsf     STATUS, RP1
        bsf     STATUS, RP0             ; bank 3
        movwf   CNT                     ; the state's flags, while the heel strike needs them
        btfss   CNT, AF_OLD
        bsf     FIN_F, FF_YOUNG

; ---- 2. heel strike -------------------------------------------------------------------------------------
        ; lo = e - hs_before; a young run starts its filters at r3
        CFGW    CFG_HS_BEFORE
        B3
        subwf   E_L, W
        movwf   LO_L
        movf    E_H, W
        btfss   STATUS, C
        decf    E_H, W
        movwf   LO_H
        btfss   FIN_F, FF_YOUNG
        goto    hs_lo_ok
        btfsc   LO_H, 7                 ; lo < 0 (young: indices below 2^15)
        goto    hs_lo_r3
        movf    LO_H, F
        btfss   STATUS, Z
        goto    hs_lo_ok
        CFGW    CFG_R3
        B3
        subwf   LO_L, W                 ; lo - r3: a borrow means lo < r3
        btfsc   STATUS, C
        goto    hs_lo_ok
hs_lo_r3:
        CFGW    CFG_R3
        B3
        movwf   LO_L
        clrf    LO_H
hs_lo_ok:
        ; samples: (e - lo) + min(hs_after, m - e) + 1
        B3
        movf    LO_L, W
        subwf   E_L, W
        movwf   CNT2                    ; e - lo (<= hs_before)
        movf    E_L, W
        subwf   FM_L, W
        movwf   TMP0
        movf    E_H, W
        btfss   STATUS, C
        incf    E_H, W
        subwf   FM_H, W                  ; W = high byte of m - e
        movwf   TMP1
        CFGW    CFG_HS_AFTER
        movwf   TMP2                    ; hs_after
        movf    TMP1, F
        btfss   STATUS, Z
        goto    hs_after_min            ; m - e >= 256: hs_after
        movf    TMP2, W
        subwf   TMP0, W                 ; (m - e) - hs_after
        btfss   STATUS, C
        goto    hs_span
hs_after_min:
        movf    TMP2, W
        movwf   TMP0
hs_span:
        incf    TMP0, W
        B3
        addwf   CNT2, W
        movwf   CNT                     ; samples to search
        CP16    TMP0, LO_L              ; j = lo
        B2
        CP16    HS_J, TMP0
        clrf    HS_K
        clrf    HS_BEST
        ; the window radius: max(r10, r5)
        CFGW    CFG_R10
        movwf   HS_R
        CFGW    CFG_R5
        subwf   HS_R, W                 ; r10 - r5
        btfsc   STATUS, C
        goto    hs_loop
        CFGW    CFG_R5
        movwf   HS_R
hs_loop:
        B2
        CP16    ARG0, HS_J
        movf    HS_R, W
        call    fir_load
        CFGW    CFG_R10
        movwf   FIR_T
        CFGW    CFG_W10_AT
        call    fir_eval                ; d10
        movlw   LOW PH1
        call    st24_w
        CFGW    CFG_R5
        movwf   FIR_T
        CFGW    CFG_W5_AT
        call    fir_eval                ; d5
        movlw   LOW FACC
        call    st32_w
        movlw   LOW PH1
        call    ld24_w
        movlw   LOW FACC
        call    sub32s_w                  ; d10 - d5 (exact in 32 bits)
        call    sat19                   ; the band, Q2.16 in 19 bits
        movf    HS_K, F
        btfsc   STATUS, Z
        goto    hs_take                 ; the first
        movlw   LOW PH0
        call    cmp24s_w
        btfsc   STATUS, Z
        goto    hs_next
        btfss   STATUS, C
        goto    hs_next                 ; not above the peak
hs_take:
        movlw   LOW PH0
        call    st24_w
        movf    HS_K, W
        movwf   HS_BEST
hs_next:
        incf    HS_K, F
        incf    HS_J, F
        btfsc   STATUS, Z
        incf    HS_J+1, F
        B3
        decfsz  CNT, F
        goto    hs_loop
        ; best = lo + HS_BEST; none when young and best < hs_delay
        B2
        movf    HS_BEST, W
        B3
        addwf   LO_L, W
        movwf   TMP0
        movf    LO_H, W
        btfsc   STATUS, C
        addlw   1
        movwf   TMP1                    ; TMP1:TMP0 = best
        btfss   FIN_F, FF_YOUNG
        goto    hs_found
        movf    TMP1, F
        btfss   STATUS, Z
        goto    hs_found
        CFGW    CFG_HS_DELAY
        subwf   TMP0, W                 ; best - delay: a borrow means best < delay
        btfsc   STATUS, C
        goto    hs_found
        B3
        movlw   0x80                    ; HEEL_STRIKE_NOT_FOUND
        movwf   REC_HS
        bsf     REC_FLAGS, SF_NO_HEEL_STRIKE
        goto    window
hs_found:
        ; heel_strike = since(best - delay, e) = best - delay - e (int8)
        CFGW    CFG_HS_DELAY
        subwf   TMP0, W
        B3
        movwf   TMP2
        movf    E_L, W
        subwf   TMP2, W
        movwf   REC_HS
        bsf     FIN_F, FF_HS

; ---- 3. the window --------------------------------------------------------------------------------------
window:
        banksel ALG_FLAGS
        btfss   ALG_FLAGS, AF_LAST
        goto    no_window
        movf    ALG_LAST_L, W
        movwf   TMP0
        movf    ALG_LAST_H, W
        movwf   TMP1
        bsf     STATUS, RP1
        bsf     STATUS, RP0             ; bank 3
        CP16    S_L, TMP0
        ; T = e - s (16-bit, signed): NO_WINDOW when T > max_step
        movf    S_L, W
        subwf   E_L, W
        movwf   TMP0
        movf    S_H, W
        btfss   STATUS, C
        incf    S_H, W
        subwf   E_H, W
        movwf   TMP1
        btfsc   TMP1, 7
        goto    win_ok                  ; negative: not above max_step
        movf    TMP1, F
        btfss   STATUS, Z
        goto    no_window
        CFGW    CFG_MAX_STEP
        subwf   TMP0, W                 ; T - max_step
        btfsc   STATUS, Z
        goto    win_ok
        btfsc   STATUS, C
        goto    no_window
win_ok:
        movf    TMP0, W
        B3
        movwf   REC_DUR
        goto    toe_off
no_window:
        bsf     STATUS, RP1
        bsf     STATUS, RP0
        bsf     REC_FLAGS, SF_NO_WINDOW
        goto    record

; ---- 4. toe-off and the events' checks -------------------------------------------------------------------
toe_off:
        ; samples: min(to_span, m - s - 1)
        movf    S_L, W
        subwf   FM_L, W
        movwf   TMP0
        movf    S_H, W
        btfss   STATUS, C
        incf    S_H, W
        subwf   FM_H, W
        movwf   TMP1                    ; m - s
        movlw   1
        subwf   TMP0, F
        btfss   STATUS, C
        decf    TMP1, F                 ; m - s - 1 (>= 0)
        CFGW    CFG_TO_SPAN
        movwf   TMP2
        movf    TMP1, F
        btfss   STATUS, Z
        goto    to_span_min
        subwf   TMP0, W                 ; (m - s - 1) - to_span
        btfss   STATUS, C
        goto    to_count
to_span_min:
        movf    TMP2, W
        movwf   TMP0
to_count:
        movf    TMP0, W
        B3
        movwf   CNT
        ; prev = d10(s), cur = d10(s + 1)
        CP16    ARG0, S_L
        D10_AT
        movlw   LOW PH0
        call    st24_w
        B3
        CP16    ARG0, S_L
        incf    ARG0, F
        btfsc   STATUS, Z
        incf    ARG1, F
        D10_AT
        movlw   LOW PH1
        call    st24_w
        movlw   1
        movwf   HS_K                    ; k: j = s + k
        B3
        movf    CNT, F
        btfsc   STATUS, Z
        goto    to_none
to_loop:
        ; nxt = d10(s + k + 1)
        B2
        incf    HS_K, W
        B3
        addwf   S_L, W
        movwf   ARG0
        movf    S_H, W
        btfsc   STATUS, C
        addlw   1
        movwf   ARG1
        D10_AT
        movlw   LOW FACC
        call    st32_w
        ; cur < prev and cur <= nxt: the toe-off
        movlw   LOW PH1
        call    ld24_w
        movlw   LOW PH0
        call    cmp24s_w
        btfsc   STATUS, Z
        goto    to_next
        btfsc   STATUS, C
        goto    to_next                 ; cur > prev
        movlw   LOW FACC
        call    cmp24s_w
        btfsc   STATUS, Z
        goto    to_found
        btfss   STATUS, C
        goto    to_found                ; cur < nxt
to_next:
        PTR     PH1                     ; prev = cur, cur = nxt
        call    ld24
        movlw   LOW PH0
        call    st24_w
        movlw   LOW FACC
        call    ld24_w
        movlw   LOW PH1
        call    st24_w
        incf    HS_K, F
        B3
        decfsz  CNT, F
        goto    to_loop
        goto    to_none
to_found:
        movf    HS_K, W
        B3
        movwf   REC_TO
        bsf     FIN_F, FF_TO
to_none:
        ; D = since(hs, s) = T + heel_strike (16-bit in TMP1:TMP0)
        B3
        movf    REC_DUR, W
        movwf   TMP0
        clrf    TMP1
        movf    REC_HS, W
        addwf   TMP0, F
        btfsc   STATUS, C
        incf    TMP1, F
        btfsc   REC_HS, 7
        decf    TMP1, F
        ; the toe-off precedes the heel strike (when there is one): to < D
        btfss   FIN_F, FF_TO
        goto    to_bad
        btfss   FIN_F, FF_HS
        goto    to_ok
        btfsc   TMP1, 7
        goto    to_bad                  ; D < 0 <= to
        movf    TMP1, F
        btfss   STATUS, Z
        goto    to_ok                   ; D >= 256 > to
        movf    REC_TO, W
        subwf   TMP0, W                 ; D - to
        btfsc   STATUS, Z
        goto    to_bad
        btfsc   STATUS, C
        goto    to_ok
to_bad:
        bcf     FIN_F, FF_TO
        clrf    REC_TO
        bsf     REC_FLAGS, SF_NO_TOE_OFF
to_ok:
        ; M3: a toe-off, a heel strike after s (D > 0), at or before e (heel_strike <= 0), after the toe-off
        btfss   FIN_F, FF_TO
        goto    m3_undef
        btfss   FIN_F, FF_HS
        goto    m3_undef
        btfsc   TMP1, 7
        goto    m3_undef                ; D < 0
        movf    TMP1, F
        btfss   STATUS, Z
        goto    m3_undef                ; D >= 256: heel_strike > 0
        movf    REC_HS, W
        btfsc   REC_HS, 7
        goto    m3_hs_le0
        btfss   STATUS, Z
        goto    m3_undef                ; heel_strike > 0
m3_hs_le0:
        movf    REC_TO, W
        subwf   TMP0, W                 ; D - to
        btfsc   STATUS, Z
        goto    m3_undef
        btfss   STATUS, C
        goto    m3_undef
        movf    TMP0, W
        movwf   HS3_OFF                 ; hs3 - s
        bsf     FIN_F, FF_HS3
        goto    range
m3_undef:
        bsf     REC_FLAGS, SF_M3_UNDEFINED

; ---- 5. M4: the range of y3 over [s, e], K4 range^p -------------------------------------------------------
range:
        B3
        CP16    ARG0, S_L
        Y3_AT
        movlw   LOW PH0
        call    st24_w                    ; maximum
        movlw   LOW PH1
        call    st24_w                    ; minimum
        B3
        movf    REC_DUR, W
        movwf   CNT
        clrf    CNT2
rg_loop:
        B3
        incf    CNT2, F
        movf    CNT2, W
        addwf   S_L, W
        movwf   ARG0
        movf    S_H, W
        btfsc   STATUS, C
        addlw   1
        movwf   ARG1
        Y3_AT
        movlw   LOW PH0
        call    upd_max24
        movlw   LOW PH1
        call    upd_min24
        B3
        decfsz  CNT, F
        goto    rg_loop
        ; range = sat19(max - min)
        movlw   LOW PH1
        call    ld24_w
        movlw   LOW FACC
        call    st32_w
        movlw   LOW PH0
        call    ld24_w
        movlw   LOW FACC
        call    sub32s_w
        call    sat19
        ; range^(1/2) (nearest): the Q2.16 range with 14 more bits, UQ1.15 root
        movlw   2 * F_ROOT_BITS - F_LP_BITS
        call    shl_u32
        call    isqrt32n
        movlw   LOW FACC
        call    st32_w                    ; the root
        CFGW    CFG_M4_EIGHTHS
        movwf   SIGNS
        movlw   CFG_K4
        call    cfg_arg16
        btfsc   SIGNS, 2
        goto    m4_sqrt
        CP16    ACC0, ARG0              ; no square root: l4 = K4
        goto    m4_put
m4_sqrt:
        movlw   LOW FACC
        call    ld32_w
        call    mul16u
        movlw   F_K4_BITS + F_ROOT_BITS - F_STEP_BITS
        call    ushr_r
        call    clip_u16
m4_put:
        B3
        CP16    REC_L4, ACC0
        movf    SIGNS, W
        andlw   3
        btfsc   STATUS, Z
        goto    pass1
        M4ROOT                          ; range^(1/4)
        btfss   SIGNS, 1
        goto    m4_eighth
        call    m4_times
m4_eighth:
        btfss   SIGNS, 0
        goto    pass1
        M4ROOT                          ; range^(1/8)
        call    m4_times

; ---- 6. pass 1: M1's double integral, c1, c2 --------------------------------------------------------------
pass1:
        PTR     P_VEL                   ; V, P, their extremes = 0
        movlw   .16
        call    clear_at
        call    open_s                  ; REM1:REM0 = a_v[s]
        B3
        movf    REC_DUR, W
        movwf   CNT
p1_loop:
        call    next_pair               ; ACC = a_j + a_j-1
        movlw   LOW P_VEL
        call    add32s_w                  ; v_new
        call    swap_vel                ; VEL = v_new, ACC = v
        movlw   LOW P_VEL
        call    add32s_w                  ; v + v_new
        movlw   LOW P_Q
        call    add32s_w
        movlw   LOW P_Q
        call    st32_w                    ; P
        movlw   LOW P_MAX
        call    upd_max32
        movlw   LOW P_MIN
        call    upd_min32
        B3
        decfsz  CNT, F
        goto    p1_loop
        call    scr_close
        ; c1 = -V / 2T (Q.17: V has 13 fraction bits, 4 more before the division)
        movlw   LOW P_VEL
        call    ld32_w
        call    neg_s32
        movlw   F_POS2_BITS - F_ACC_BITS
        call    shl_s32
        B3
        movf    REC_DUR, W
        movwf   ARG0
        clrf    ARG1
        bcf     STATUS, C
        rlf     ARG0, F
        rlf     ARG1, F
        call    divr32s
        movlw   LOW P_RAMP
        call    st32_w                    ; c1
        ; c2 = (16 P + 2 (c1 T^2)) / T
        B3
        movf    REC_DUR, W
        call    mul_count
        movlw   1
        call    shl_s32
        movlw   LOW P_VEL
        call    st32_w
        movlw   LOW P_Q
        call    ld32_w
        movlw   F_POS2_BITS - F_ACC_BITS
        call    shl_s32
        movlw   LOW P_VEL
        call    add32s_w
        B3
        movf    REC_DUR, W
        movwf   ARG0
        clrf    ARG1
        call    divr32s
        PTR     P_C2
        call    st32                    ; c2
        bsf     STATUS, IRP
        ; M1 = K1 2 sqrt(2 l h - h^2), h from P's range
        movlw   LOW P_MAX
        call    ld32_w
        movlw   LOW P_MIN
        call    sub32s_w
        movlw   CFG_EXC1
        call    excursion
        movlw   F_EXC_BITS - F_TWO_LEN_BITS
        call    pendulum
        xorlw   0
        btfss   STATUS, Z
        goto    m1_impossible
        movlw   CFG_K1
        call    times_k
        B3
        CP16    REC_L1, ACC0
        goto    pass2
m1_impossible:
        B3
        bsf     REC_FLAGS, SF_IMPOSSIBLE

; ---- 7. pass 2: M2's corrected position, M3's single support ---------------------------------------------
pass2:
        PTR     P_RAMP                  ; ramp step 4 c1, ramp 2 c1
        call    ld32
        movlw   2
        call    shl_s32
        movlw   LOW P_RSTEP
        call    st32_w
        movlw   LOW P_RAMP
        call    ld32_w
        movlw   1
        call    shl_s32
        movlw   LOW P_RAMP
        call    st32_w
        PTR     P_VEL                   ; V, p2, extremes = 0
        movlw   .24
        call    clear_at
        call    open_s
        B3
        movf    REC_DUR, W
        movwf   CNT
        clrf    CNT2                    ; k = j - s
p2_loop:
        B3
        incf    CNT2, F
        call    next_pair
        movlw   LOW P_VEL
        call    add32s_w                  ; v_new
        call    swap_vel
        movlw   LOW P_VEL
        call    add32s_w                  ; v + v_new
        movlw   F_POS2_BITS - F_ACC_BITS
        call    shl_s32                 ; dp, Q.17
        PTR     P_C2
        call    sub32s
        bsf     STATUS, IRP
        movlw   LOW P_RAMP
        call    add32s_w
        movlw   LOW P_Q
        call    add32s_w
        movlw   LOW P_Q
        call    st32_w                    ; p2
        movlw   LOW P_MAX
        call    upd_max32
        movlw   LOW P_MIN
        call    upd_min32
        ; single support: M3 defined, to <= j <= hs3
        B3
        btfss   FIN_F, FF_HS3
        goto    p2_ramp
        movf    REC_TO, W
        subwf   CNT2, W                 ; k - to
        btfss   STATUS, C
        goto    p2_ramp
        movf    CNT2, W
        subwf   HS3_OFF, W              ; hs3 - k
        btfss   STATUS, C
        goto    p2_ramp
        btfsc   FIN_F, FF_SEEN
        goto    p2_seen
        bsf     FIN_F, FF_SEEN
        movlw   LOW P_SMAX
        call    st32_w
        movlw   LOW P_SMIN
        call    st32_w
        goto    p2_ramp
p2_seen:
        movlw   LOW P_SMAX
        call    upd_max32
        movlw   LOW P_SMIN
        call    upd_min32
p2_ramp:
        movlw   LOW P_RAMP
        call    ld32_w
        movlw   LOW P_RSTEP
        call    add32s_w
        movlw   LOW P_RAMP
        call    st32_w
        B3
        decfsz  CNT, F
        goto    p2_loop
        call    scr_close
        ; M2
        movlw   LOW P_MAX
        call    ld32_w
        movlw   LOW P_MIN
        call    sub32s_w
        movlw   CFG_EXC2
        call    excursion
        movlw   F_EXC2_BITS - F_TWO_LEN_BITS
        call    pendulum
        xorlw   0
        btfss   STATUS, Z
        goto    m2_impossible
        movlw   CFG_K2
        call    times_k
        B3
        CP16    REC_L2, ACC0
        goto    m3
m2_impossible:
        B3
        bsf     REC_FLAGS, SF_IMPOSSIBLE
m3:
        B3
        ; M3 = 2 sqrt(2 l h1 - h1^2) + foot
        btfss   FIN_F, FF_HS3
        goto    m5
        movlw   LOW P_SMAX
        call    ld32_w
        movlw   LOW P_SMIN
        call    sub32s_w
        movlw   CFG_EXC2
        call    excursion
        movlw   F_EXC2_BITS - F_TWO_LEN_BITS
        call    pendulum
        xorlw   0
        btfss   STATUS, Z
        goto    m3_impossible
        movlw   CFG_FOOT
        call    cfg_arg16
        movf    ARG0, W                 ; length + foot, UQ2.14 saturated
        addwf   ACC0, F
        movf    ARG1, W
        btfsc   STATUS, C
        incfsz  ARG1, W
        addwf   ACC1, F
        btfss   STATUS, C
        goto    m3_put
        movlw   0xFF
        movwf   ACC0
        movwf   ACC1
        bsf     FLAGS, FLAG_SAT
m3_put:
        B3
        CP16    REC_L3, ACC0
        goto    m5
m3_impossible:
        B3
        bsf     REC_FLAGS, SF_IMPOSSIBLE

; ---- 8. M5, the flags, the CRC, the state -----------------------------------------------------------------
m5:
        B2
        movlw   CFG_K2M5                ; K2 into FACC
        movwf   FIR_W
        PTR     FACC
m5_k2:
        movf    FIR_W, W
        call    ee_cfg
        movwf   INDF
        incf    FSR, F
        incf    FIR_W, F
        movlw   CFG_K2M5 + 4
        xorwf   FIR_W, W
        btfss   STATUS, Z
        goto    m5_k2
        movlw   CFG_K1FS
        call    cfg_arg16
        CP16    ACC0, ARG0
        movlw   CFG_K1FS + 2
        call    cfg_arg16
        CP16    ACC2, ARG0
        B3
        movf    REC_DUR, W
        movwf   ARG0
        clrf    ARG1
        call    divr32s                 ; K1 fs / T
        movlw   LOW FACC
        call    add32s_w                  ; + K2
        movlw   F_M5_BITS - F_STEP_BITS
        movwf   ARG0
        call    shr32r
        call    clip_s2u16
        B3
        CP16    REC_L5, ACC0
record:
        B3
        btfsc   FLAGS, FLAG_SAT
        bsf     REC_FLAGS, SF_SATURATED
        bcf     FLAGS, FLAG_SAT
        CFGW    CFG_REC_FLAGS
        B3
        iorwf   REC_FLAGS, F
        call    rec_crc
        ; the state: LAST = e, F_LAST; F_LAST_WEAK = F_PEND_WEAK; F_PEND_WEAK cleared
        B3
        movf    E_L, W
        movwf   TMP0
        movf    E_H, W
        movwf   TMP1
        banksel ALG_FLAGS
        movf    TMP0, W
        movwf   ALG_LAST_L
        movf    TMP1, W
        movwf   ALG_LAST_H
        bsf     ALG_FLAGS, AF_LAST
        bcf     ALG_FLAGS, AF_LAST_WEAK
        btfsc   ALG_FLAGS, AF_PEND_WEAK
        bsf     ALG_FLAGS, AF_LAST_WEAK
        bcf     ALG_FLAGS, AF_PEND_WEAK
        bcf     STATUS, RP0
        bcf     STATUS, RP1
#ifdef FINALISE_FAR
        bcf     STATUS, IRP             ; the logger: back to steps 4-5 in page 0 (bank 0, IRP = 0)
        clrf    PCLATH
#endif
        return

; ==========================================================================================================
; helpers of finalise (one level below it unless noted)

; open_s: the sequential read of a_v[s ..]; REM1:REM0 = a_v[s].
open_s:
        B3
        CP16    ARG0, S_L
        call    scr_open
        call    scr_next
        movf    TMP0, W
        movwf   REM0
        movf    TMP1, W
        movwf   REM1
        return

; next_pair: ACC = a_v[j] + a_v[j-1] (32-bit), the next sample read; REM1:REM0 = a_v[j].
next_pair:
        call    scr_next                ; TMP1:TMP0 = a_v[j]
        movf    REM0, W
        movwf   ACC0
        movf    REM1, W
        movwf   ACC1
        movf    TMP0, W
        addwf   ACC0, F
        movf    TMP1, W
        btfsc   STATUS, C
        incfsz  TMP1, W
        addwf   ACC1, F
        movlw   0                       ; the high half: carry + both sign extensions (-2 .. 1)
        btfsc   STATUS, C
        movlw   1
        btfsc   REM1, 7
        addlw   0xFF
        btfsc   TMP1, 7
        addlw   0xFF
        movwf   ACC2
        clrf    ACC3
        btfsc   ACC2, 7
        decf    ACC3, F
        movf    TMP0, W
        movwf   REM0
        movf    TMP1, W
        movwf   REM1
        return

; swap_vel: exchange ACC and P_VEL (bank 2).
swap_vel:
        B2
        movf    ACC0, W
        xorwf   P_VEL, W
        xorwf   ACC0, F
        xorwf   P_VEL, F
        movf    ACC1, W
        xorwf   P_VEL+1, W
        xorwf   ACC1, F
        xorwf   P_VEL+1, F
        movf    ACC2, W
        xorwf   P_VEL+2, W
        xorwf   ACC2, F
        xorwf   P_VEL+2, F
        movf    ACC3, W
        xorwf   P_VEL+3, W
        xorwf   ACC3, F
        xorwf   P_VEL+3, F
        return

; clear_at: W bytes from FSR on = 0.
clear_at:
        movwf   COUNT
ca_byte:
        clrf    INDF
        incf    FSR, F
        decfsz  COUNT, F
        goto    ca_byte
        return

; m4_times: REC_L4 = sat16u(REC_L4 FACC >> 15, rounded).
m4_times:
        B3
        CP16    ARG0, REC_L4
        movlw   LOW FACC
        call    ld32_w
        call    mul16u
        movlw   F_STEP_BITS + F_ROOT_BITS - F_STEP_BITS
        call    ushr_r
        call    clip_u16
        B3
        CP16    REC_L4, ACC0
        return

; excursion: ACC = a position range (>= 0) -> ACC1:ACC0 = h (U16): the range rounded by the shift at
; configuration offset W, then times the unit, rounded by the shift at W + 1 (kernel _excursion).
excursion:
        movwf   SIGNS
        call    ee_cfg
        movwf   ARG0
        call    shr32r
        call    clip_u16
        movlw   CFG_UNIT
        call    cfg_arg16
        call    mul16u
        incf    SIGNS, W
        call    ee_cfg
        call    ushr_r
        call    clip_u16
        B2
        CP16    P_H, ACC0
        return

; pendulum: P_H = h (f_h fraction bits; W = f_h - 14: 2 for M1, 4 for M2/M3) -> W = 0 and ACC1:ACC0 =
; 2 sqrt(2 l h - h^2) in UQ2.14, or W = 1 when h^2 > 2 l h (kernel _pendulum).
pendulum:
        movwf   SIGNS
        movlw   CFG_TWO_LEG
        call    cfg_arg16
        CP16    ACC0, P_H
        call    mul16u                  ; 2 l h, exact
        movlw   LOW P_LH2
        call    st32_w
        CP16    ACC0, P_H
        CP16    ARG0, P_H
        call    mul16u
        movf    SIGNS, W
        call    ushr_r                  ; h^2, rounded to 14 + f_h fraction bits
        movlw   LOW P_Q
        call    st32_w
        movlw   LOW P_LH2
        call    ld32_w
        movlw   LOW P_Q
        call    usub32_w                  ; 2 l h - h^2
        btfss   STATUS, C
        retlw   1
        call    isqrt32                 ; floor, (14 + f_h) / 2 fraction bits
        bcf     STATUS, C
        rlf     ACC0, F                 ; twice
        rlf     ACC1, F
        rlf     ACC2, F
        bcf     STATUS, C
        rrf     SIGNS, W                ; to 14 fraction bits, rounded
        call    ushr_r
        call    clip_u16
        retlw   0

; times_k: ACC1:ACC0 = sat16u((ACC1:ACC0 K + 2^14) >> 15), K the configuration word at offset W (UQ1.15).
times_k:
        call    cfg_arg16
        call    mul16u
        movlw   F_K_BITS
        call    ushr_r
        goto    clip_u16

; mul_count: ACC = sat32(ACC T^2), T = W (kernel ar.mul_count: c1 times the squared duration).
mul_count:
        movwf   ARG0
        clrf    ARG1
        clrf    SIGNS
        btfss   ACC3, 7
        goto    mc_pos
        call    neg_acc
        incf    SIGNS, F
mc_pos:
        movf    ACC0, W
        movwf   TMP0
        movf    ACC1, W
        movwf   TMP1
        movf    ACC2, W
        movwf   REM0
        movf    ACC3, W
        movwf   REM1
        movf    ARG0, W
        movwf   ACC0
        clrf    ACC1
        call    mul16u                  ; T^2
        CP16    ARG0, ACC0
        CP16    ACC0, TMP0
        call    mul16u                  ; low half of |c1| times T^2
        movf    ACC0, W
        movwf   TMP0
        movf    ACC1, W
        movwf   TMP1
        movf    ACC2, W
        movwf   TMP2
        movf    ACC3, W
        movwf   REM2
        CP16    ACC0, REM0
        call    mul16u                  ; high half
        movf    ACC0, W                 ; 48-bit sum: low + high << 16
        addwf   TMP2, F
        movf    ACC1, W
        btfsc   STATUS, C
        incfsz  ACC1, W
        addwf   REM2, F
        btfss   STATUS, C
        goto    mc_carry
        incf    ACC2, F
        btfsc   STATUS, Z
        incf    ACC3, F
mc_carry:
        movf    ACC2, W
        iorwf   ACC3, W
        btfss   STATUS, Z
        goto    mc_sat
        movf    TMP0, W
        movwf   ACC0
        movf    TMP1, W
        movwf   ACC1
        movf    TMP2, W
        movwf   ACC2
        movf    REM2, W
        movwf   ACC3
        btfsc   SIGNS, 0
        goto    mc_neg
        btfsc   ACC3, 7
        goto    mc_sat
        return
mc_neg:
        btfss   ACC3, 7
        goto    neg_acc                 ; below 2^31: negate
        movf    ACC3, W                 ; 2^31 exactly is -2^31
        xorlw   0x80
        iorwf   ACC2, W
        iorwf   ACC1, W
        iorwf   ACC0, W
        btfsc   STATUS, Z
        return
mc_sat:
        clrf    REM2
        btfsc   SIGNS, 0
        bsf     REM2, 7
        goto    sat32_by_rem2

; rec_crc: REC+18..19 = CRC-16/XMODEM of REC+0..17, big-endian.
rec_crc:
        clrf    TMP0
        clrf    TMP1
        PTR     REC
        movlw   .18
        movwf   COUNT
rc_byte:
        movf    INDF, W
        xorwf   TMP1, F
        movlw   8
        movwf   TMP2
rc_bit:
        bcf     STATUS, C
        rlf     TMP0, F
        rlf     TMP1, F
        btfss   STATUS, C
        goto    rc_next
        movlw   0x21
        xorwf   TMP0, F
        movlw   0x10
        xorwf   TMP1, F
rc_next:
        decfsz  TMP2, F
        goto    rc_bit
        incf    FSR, F
        decfsz  COUNT, F
        goto    rc_byte
        movf    TMP1, W
        movwf   INDF
        incf    FSR, F
        movf    TMP0, W
        movwf   INDF
        return

; ---- the FIR on the scratch ring --------------------------------------------------------------------------
; fir_load: ARG1:ARG0 = c, W = R -> WBUF[0] = a_v[c], WBUF[t] = sat16(a_v[c-t] + a_v[c+t]), t = 1 .. R
; (one sequential read of 2R + 1 samples).
fir_load:
        B2
        movwf   FIR_T
        movwf   FIR_W                   ; R, for the second half
        subwf   ARG0, F                 ; c - R
        btfss   STATUS, C
        decf    ARG1, F
        call    scr_open
        B2
        bcf     STATUS, C
        rlf     FIR_T, W
        addlw   LOW WBUF
        movwf   FSR                     ; WBUF[R]
        bsf     STATUS, IRP
        incf    FIR_T, F                ; a_v[c-R] .. a_v[c]
fl_low:
        call    scr_next
        movf    TMP0, W
        movwf   INDF
        incf    FSR, F
        movf    TMP1, W
        movwf   INDF
        movlw   3
        subwf   FSR, F
        decfsz  FIR_T, F
        goto    fl_low
        movf    FIR_W, W
        btfsc   STATUS, Z
        goto    scr_close
        movwf   FIR_T
        movlw   LOW WBUF + 2
        movwf   FSR
fl_high:
        call    scr_next                ; a_v[c+t]
        movf    TMP1, W
        movwf   TMP2                    ; its sign
        movf    INDF, W
        addwf   TMP0, F
        incf    FSR, F
        movf    INDF, W
        btfsc   STATUS, C
        incfsz  INDF, W
        addwf   TMP1, F
        movf    INDF, W                 ; overflow: both of one sign, the sum of the other
        xorwf   TMP2, W
        andlw   0x80
        btfss   STATUS, Z
        goto    fl_put
        movf    TMP1, W
        xorwf   TMP2, W
        andlw   0x80
        btfsc   STATUS, Z
        goto    fl_put
        bsf     FLAGS, FLAG_SAT
        movlw   0xFF
        movwf   TMP0
        movlw   0x7F
        movwf   TMP1
        btfss   TMP2, 7
        goto    fl_put
        clrf    TMP0
        movlw   0x80
        movwf   TMP1
fl_put:
        movf    TMP1, W
        movwf   INDF
        decf    FSR, F
        movf    TMP0, W
        movwf   INDF
        incf    FSR, F
        incf    FSR, F
        decfsz  FIR_T, F
        goto    fl_high
        goto    scr_close

; fir_eval: FIR_T = r, W = configuration offset of the weights w0 .. wr -> ACC = the FIR at the loaded window:
; sat19((w0 a + sum sat32 w_t pair_t + 2^10) >> 11) (kernel _fir), sign-extended.
fir_eval:
        B2
        movwf   FIR_W
        movlw   LOW WBUF
        movwf   TMP2                    ; the entry
        call    fir_tap
        movf    ACC0, W
        movwf   FACC
        movf    ACC1, W
        movwf   FACC+1
        movf    ACC2, W
        movwf   FACC+2
        movf    ACC3, W
        movwf   FACC+3
fe_tap:
        movf    FIR_T, F
        btfsc   STATUS, Z
        goto    fe_done
        call    fir_tap
        movlw   LOW FACC
        call    add32s_w
        movlw   LOW FACC
        call    st32_w
        decf    FIR_T, F
        goto    fe_tap
fe_done:
        movlw   LOW FACC
        call    ld32_w
        movlw   F_FIR_BITS - F_LP_BITS
        movwf   ARG0
        call    shr32r
        goto    sat19

; fir_tap: ACC = (weight at FIR_W) (entry at FSR = TMP2), signed; FIR_W and TMP2 advance.
fir_tap:
        movf    FIR_W, W
        call    ee_cfg
        movwf   ARG0
        incf    FIR_W, F
        movf    FIR_W, W
        call    ee_cfg
        movwf   ARG1
        incf    FIR_W, F
        movf    TMP2, W
        movwf   FSR
        bsf     STATUS, IRP
        movf    INDF, W
        movwf   ACC0
        incf    FSR, F
        movf    INDF, W
        movwf   ACC1
        incf    TMP2, F
        incf    TMP2, F
        goto    mul16s

; ---- 32-bit words at FSR (IRP selects the bank pair) ------------------------------------------------------
ld32_w:
        movwf   FSR
ld32:                                   ; ACC = [FSR]
        movf    INDF, W
        movwf   ACC0
        incf    FSR, F
        movf    INDF, W
        movwf   ACC1
        incf    FSR, F
        movf    INDF, W
        movwf   ACC2
        incf    FSR, F
        movf    INDF, W
        movwf   ACC3
        return
ld24_w:
        movwf   FSR
ld24:                                   ; ACC = [FSR] (24-bit, sign-extended)
        movf    INDF, W
        movwf   ACC0
        incf    FSR, F
        movf    INDF, W
        movwf   ACC1
        incf    FSR, F
        movf    INDF, W
        movwf   ACC2
        clrf    ACC3
        btfsc   ACC2, 7
        decf    ACC3, F
        return
st32_w:
        movwf   FSR
st32:                                   ; [FSR] = ACC
        movf    ACC0, W
        movwf   INDF
        incf    FSR, F
        movf    ACC1, W
        movwf   INDF
        incf    FSR, F
        movf    ACC2, W
        movwf   INDF
        incf    FSR, F
        movf    ACC3, W
        movwf   INDF
        return
st24_w:
        movwf   FSR
st24:                                   ; [FSR] = ACC2..ACC0
        movf    ACC0, W
        movwf   INDF
        incf    FSR, F
        movf    ACC1, W
        movwf   INDF
        incf    FSR, F
        movf    ACC2, W
        movwf   INDF
        return

; add32s / sub32s: ACC = ACC +- [FSR], saturated to the signed 32-bit word (FLAG_SAT); REM2 = A's sign.
add32s_w:
        movwf   FSR
add32s:
        movf    ACC3, W
        movwf   REM2
        movf    INDF, W
        addwf   ACC0, F
        incf    FSR, F
        movf    INDF, W
        btfsc   STATUS, C
        incfsz  INDF, W
        addwf   ACC1, F
        incf    FSR, F
        movf    INDF, W
        btfsc   STATUS, C
        incfsz  INDF, W
        addwf   ACC2, F
        incf    FSR, F
        movf    INDF, W
        btfsc   STATUS, C
        incfsz  INDF, W
        addwf   ACC3, F
        movf    INDF, W                 ; operands of different signs: no overflow
        xorwf   REM2, W
        andlw   0x80
        btfss   STATUS, Z
        return
ovf_check:
        movf    ACC3, W                 ; the result keeps A's sign: no overflow
        xorwf   REM2, W
        andlw   0x80
        btfsc   STATUS, Z
        return
sat32_by_rem2:                          ; ACC = 2^31 - 1 (REM2 >= 0) or -2^31, FLAG_SAT
        bsf     FLAGS, FLAG_SAT
        movlw   0xFF
        movwf   ACC0
        movwf   ACC1
        movwf   ACC2
        movlw   0x7F
        movwf   ACC3
        btfss   REM2, 7
        return
        clrf    ACC0
        clrf    ACC1
        clrf    ACC2
        movlw   0x80
        movwf   ACC3
        return
sub32s_w:
        movwf   FSR
sub32s:
        movf    ACC3, W
        movwf   REM2
        movf    INDF, W
        subwf   ACC0, F
        incf    FSR, F
        movf    INDF, W
        btfss   STATUS, C
        incfsz  INDF, W
        subwf   ACC1, F
        incf    FSR, F
        movf    INDF, W
        btfss   STATUS, C
        incfsz  INDF, W
        subwf   ACC2, F
        incf    FSR, F
        movf    INDF, W
        btfss   STATUS, C
        incfsz  INDF, W
        subwf   ACC3, F
        movf    INDF, W                 ; operands of one sign: no overflow
        xorwf   REM2, W
        andlw   0x80
        btfsc   STATUS, Z
        return
        goto    ovf_check

; usub32: ACC = ACC - [FSR] (unsigned); C = 0 when it borrowed.
usub32_w:
        movwf   FSR
usub32:
        movf    INDF, W
        subwf   ACC0, F
        incf    FSR, F
        movf    INDF, W
        btfss   STATUS, C
        incfsz  INDF, W
        subwf   ACC1, F
        incf    FSR, F
        movf    INDF, W
        btfss   STATUS, C
        incfsz  INDF, W
        subwf   ACC2, F
        incf    FSR, F
        movf    INDF, W
        btfss   STATUS, C
        incfsz  INDF, W
        subwf   ACC3, F
        return

; cmp32s / cmp24s: ACC against [FSR], signed -> Z = equal; otherwise C = 1 when ACC > [FSR]. Uses REM2.
CMPTOP  macro
        xorlw   0x80
        movwf   REM2
        movf    INDF, W
        xorlw   0x80
        subwf   REM2, W
        btfss   STATUS, Z
        return
        endm
cmp32s_w:
        movwf   FSR
cmp32s:
        movlw   3
        addwf   FSR, F
        movf    ACC3, W
        CMPTOP
        decf    FSR, F
        movf    INDF, W
        subwf   ACC2, W
        btfss   STATUS, Z
        return
        goto    cmp_b1
cmp24s_w:
        movwf   FSR
cmp24s:
        movlw   2
        addwf   FSR, F
        movf    ACC2, W
        CMPTOP
cmp_b1:
        decf    FSR, F
        movf    INDF, W
        subwf   ACC1, W
        btfss   STATUS, Z
        return
        decf    FSR, F
        movf    INDF, W
        subwf   ACC0, W
        return

; upd_max32 / upd_min32 / upd_max24 / upd_min24: the word at W (bank 2 or 3 by IRP) = max / min of it and ACC.
upd_max32:
        movwf   SIGNS
        movwf   FSR
        call    cmp32s
        btfsc   STATUS, Z
        return
        btfss   STATUS, C
        return
        goto    st_at32
upd_min32:
        movwf   SIGNS
        movwf   FSR
        call    cmp32s
        btfsc   STATUS, Z
        return
        btfsc   STATUS, C
        return
st_at32:
        movf    SIGNS, W
        movwf   FSR
        goto    st32
upd_max24:
        movwf   SIGNS
        movwf   FSR
        call    cmp24s
        btfsc   STATUS, Z
        return
        btfss   STATUS, C
        return
        goto    st_at24
upd_min24:
        movwf   SIGNS
        movwf   FSR
        call    cmp24s
        btfsc   STATUS, Z
        return
        btfsc   STATUS, C
        return
st_at24:
        movf    SIGNS, W
        movwf   FSR
        goto    st24

; ---- shifts and clips of ACC ------------------------------------------------------------------------------
; shl_s32: ACC = sat32(ACC << W), signed. shl_u32: unsigned.
shl_s32:
        movwf   COUNT
        movf    COUNT, F
        btfsc   STATUS, Z
        return
        movf    ACC3, W
        movwf   REM2
ss_bit:
        movf    ACC3, W                 ; bits 31 and 30 differ: the shift overflows
        andlw   0xC0
        btfsc   STATUS, Z
        goto    ss_ok
        xorlw   0xC0
        btfss   STATUS, Z
        goto    sat32_by_rem2
ss_ok:
        bcf     STATUS, C
        rlf     ACC0, F
        rlf     ACC1, F
        rlf     ACC2, F
        rlf     ACC3, F
        decfsz  COUNT, F
        goto    ss_bit
        return
shl_u32:
        movwf   COUNT
        movf    COUNT, F
        btfsc   STATUS, Z
        return
su_bit:
        btfsc   ACC3, 7
        goto    su_sat
        bcf     STATUS, C
        rlf     ACC0, F
        rlf     ACC1, F
        rlf     ACC2, F
        rlf     ACC3, F
        decfsz  COUNT, F
        goto    su_bit
        return
su_sat:
        movlw   0xFF
        movwf   ACC0
        movwf   ACC1
        movwf   ACC2
        movwf   ACC3
        bsf     FLAGS, FLAG_SAT
        return

; ushr_r: ACC = (ACC + 2^(W-1)) >> W, unsigned 32-bit (the sum's 33rd bit kept); W = 0: unchanged.
ushr_r:
        movwf   COUNT
        movf    COUNT, F
        btfsc   STATUS, Z
        return
        decf    COUNT, F
        btfsc   STATUS, Z
        goto    ur_last
ur_bit:
        bcf     STATUS, C
        rrf     ACC3, F
        rrf     ACC2, F
        rrf     ACC1, F
        rrf     ACC0, F
        decfsz  COUNT, F
        goto    ur_bit
ur_last:
        incf    ACC0, F
        btfsc   STATUS, Z
        incf    ACC1, F
        btfsc   STATUS, Z
        incf    ACC2, F
        btfsc   STATUS, Z
        incf    ACC3, F
        bcf     STATUS, C
        btfsc   STATUS, Z
        bsf     STATUS, C               ; the carry out of the increment
        rrf     ACC3, F
        rrf     ACC2, F
        rrf     ACC1, F
        rrf     ACC0, F
        return

; neg_s32: ACC = sat32(-ACC).
neg_s32:
        movf    ACC3, W
        xorlw   0x80
        iorwf   ACC2, W
        iorwf   ACC1, W
        iorwf   ACC0, W
        btfss   STATUS, Z
        goto    neg_acc
        clrf    REM2
        goto    sat32_by_rem2

; sat19: ACC (signed) clipped to the 19-bit word -2^18 .. 2^18 - 1 (the FIR outputs' W_LP).
sat19:
        movf    ACC2, W
        andlw   0xFC
        movwf   REM2
        movf    ACC3, W
        btfsc   STATUS, Z
        goto    s19_pos
        xorlw   0xFF
        btfss   STATUS, Z
        goto    s19_clip
        movf    REM2, W
        xorlw   0xFC
        btfsc   STATUS, Z
        return
        goto    s19_clip
s19_pos:
        movf    REM2, F
        btfsc   STATUS, Z
        return
s19_clip:
        bsf     FLAGS, FLAG_SAT
        btfsc   ACC3, 7
        goto    s19_neg
        movlw   0xFF
        movwf   ACC0
        movwf   ACC1
        movlw   0x03
        movwf   ACC2
        clrf    ACC3
        return
s19_neg:
        clrf    ACC0
        clrf    ACC1
        movlw   0xFC
        movwf   ACC2
        movlw   0xFF
        movwf   ACC3
        return

; clip_u16: ACC (>= 0) clipped to 0 .. 65535; clip_s2u16: ACC (signed) clipped to 0 .. 65535.
clip_s2u16:
        btfss   ACC3, 7
        goto    clip_u16
        clrf    ACC0
        clrf    ACC1
        clrf    ACC2
        clrf    ACC3
        bsf     FLAGS, FLAG_SAT
        return
clip_u16:
        movf    ACC2, W
        iorwf   ACC3, W
        btfsc   STATUS, Z
        return
        movlw   0xFF
        movwf   ACC0
        movwf   ACC1
        clrf    ACC2
        clrf    ACC3
        bsf     FLAGS, FLAG_SAT
        return

; ---- the configuration (data EEPROM) ---------------------------------------------------------------------
; ee_cfg: W = the configuration byte at offset W (leaves bank 2).
ee_cfg:
        addlw   STEP_CFG_EE
        bsf     STATUS, RP1
        bcf     STATUS, RP0
        movwf   EEADR
        bsf     STATUS, RP0
        bcf     EECON1, EEPGD
        bsf     EECON1, RD
        bcf     STATUS, RP0
        movf    EEDATA, W
        return
; cfg_arg16: ARG1:ARG0 = the configuration word at offset W.
cfg_arg16:
        movwf   COUNT
        call    ee_cfg
        movwf   ARG0
        incf    COUNT, W
        call    ee_cfg
        movwf   ARG1
        return

; ---- the scratch ring ---------------------------------------------------------------------------------------
; scr_open: a sequential read of a_v from sample index ARG1:ARG0; scr_next: TMP1:TMP0 = the next sample
; (Q2.13, LE); scr_close: the read's end. Bank 2 on return.
#ifdef SCR_TABLE
; Test build: the ring's samples are a table in program memory at SCR_TABLE (two words a sample, its low and
; high byte), sample index SCR_J0 first; read with the flash read (EECON1 EEPGD). The bench keeps every read
; of a segment's steps inside the table.
scr_open:
        bsf     STATUS, RP1
        bcf     STATUS, RP0
        movlw   LOW SCR_J0
        subwf   ARG0, W
        movwf   EEADR
        movf    ARG1, W
        btfss   STATUS, C
        addlw   0xFF
        addlw   (0x100 - HIGH SCR_J0) & 0xFF
        movwf   EEADRH                  ; j - SCR_J0
        bcf     STATUS, C
        rlf     EEADR, F
        rlf     EEADRH, F
        movlw   HIGH SCR_TABLE
        addwf   EEADRH, F
        return
scr_next:
        bsf     STATUS, RP0             ; bank 3
        bsf     EECON1, EEPGD
        bsf     EECON1, RD
        nop
        nop
        bcf     STATUS, RP0             ; bank 2
        movf    EEDATA, W
        movwf   TMP0
        incf    EEADR, F                ; the sample's second word (even + 1: no carry)
        bsf     STATUS, RP0
        bsf     EECON1, RD
        nop
        nop
        bcf     STATUS, RP0
        movf    EEDATA, W
        movwf   TMP1
        incf    EEADR, F
        btfsc   STATUS, Z
        incf    EEADRH, F
        return
scr_close:
        return
#else
; The scratch ring on the I2C bus: the MSSP in I2C master mode (SSPCON = 0x28, SSPADD set by the firmware's
; start-up, RC3 = SCL, RC4 = SDA, pull-ups), a random read to set the EEPROM's address counter, then a
; sequential read, each byte acknowledged; scr_close reads one byte more, not acknowledged, and stops.
; The ring: SCR_SAMPLES samples (kernel.py SCRATCH_RING_SAMPLES, a multiple of 256 up to 32,768), two bytes
; each (LE), from byte 0 of the device SCR_CONTROL answers to: 0xA8, the logger's 24LC1025 (1010 B0 A1 A0 R/W)
; with the block select B0 = 1 for the second 64 KiB block and A1 = A0 = 0 (its A2 pin tied high), up to
; the header slots. Sample index j is at ring sample K + j (SCR_K, 16 bits, scr_write), plus SCR_SAMPLES when
; that is negative (a sample written before the ring's last wrap, which took SCR_SAMPLES off K). The
; EEPROM's address counter does not wrap with the ring (the 24LC1025's runs on from the ring's end into the
; header slots): a read that reaches the ring's end is stopped and opened again at ring sample 0.
; The bench's 24xx256 (1010 A2 A1 A0 R/W) answers 0xA8 with its A2 pin pulled high and ignores the address's
; bit 15: ring samples p and p + 16,384 share a byte there.
; The waits are in line: scr_open and scr_next run at most one level below finalise's helpers.
#ifndef SCR_CONTROL
#define SCR_CONTROL     0xA8
#endif
    if LOW (SCR_SAMPLES) != 0 || SCR_SAMPLES > 0x8000
        error "the scratch ring's samples must be a multiple of 256 up to 32,768"
    endif
        #include "i2c.inc"

; i2c_tx: send W, wait for the acknowledge slot (the acknowledge itself is not checked).
i2c_tx:
        bcf     STATUS, RP0
        bcf     STATUS, RP1
        movwf   SSPBUF
        I2C_WAIT
        return
scr_open:
        bcf     STATUS, RP1             ; bank 0: SCR_POS = K + j, plus SCR_SAMPLES when negative
        bcf     STATUS, RP0
        movf    SCR_K_L, W
        addwf   ARG0, W
        movwf   SCR_POS
        movf    SCR_K_H, W
        btfsc   STATUS, C
        addlw   1
        addwf   ARG1, W
        movwf   SCR_POS+1
        movlw   HIGH (SCR_SAMPLES)
        btfsc   SCR_POS+1, 7
        addwf   SCR_POS+1, F
scr_at:                                 ; a random read from ring sample SCR_POS (byte 2 SCR_POS)
        I2C_CMD SEN
        movlw   SCR_CONTROL
        call    i2c_tx
        rlf     SCR_POS, W              ; C = bit 7 of the low byte
        rlf     SCR_POS+1, W
        call    i2c_tx
        bcf     STATUS, C
        rlf     SCR_POS, W
        call    i2c_tx
        I2C_CMD RSEN
        movlw   SCR_CONTROL | 1
        call    i2c_tx
        bsf     STATUS, RP1             ; bank 2
        return
scr_next:
        I2C_CMD RCEN
        movf    SSPBUF, W
        movwf   TMP0
        I2C_ACK 0
        I2C_CMD RCEN
        movf    SSPBUF, W
        movwf   TMP1
        incf    SCR_POS, F              ; bank 0: the next sample's ring sample
        btfss   STATUS, Z
        goto    sn_ack
        incf    SCR_POS+1, F
        movf    SCR_POS+1, W
        xorlw   HIGH (SCR_SAMPLES)
        btfss   STATUS, Z
        goto    sn_ack
        clrf    SCR_POS+1               ; the ring's end: the byte not acknowledged, stop, read on from ring sample 0
        call    scr_stop
        goto    scr_at
sn_ack:
        I2C_ACK 0
        bsf     STATUS, RP1             ; bank 2
        return
scr_close:
        I2C_CMD RCEN
scr_stop:
        I2C_ACK 1
        I2C_CMD PEN
        bsf     STATUS, RP1
        return
#endif
