; Steps 4 and 5 of the on-line algorithm (kernel.py): the a_v delay line and the centred 3 Hz FIR
; (stage_fir, kernel._front's step 4 and kernel._fir), the foot-flat detector (stage_detect: kernel._sample's
; step 5, _prominence, _confirmed, _median_twice, parameters.minimum_distance, _weak_peak, _stop_candidate),
; finalise (the end of kernel._finalise; the step record itself is step_record.asm's), and step_flush
; (kernel.flush: STOP's finalise).
;
; The code runs in bank 0 and reaches the state in bank 1 through FSR (IRP = 0: FSR spans banks 0 and 1,
; and the kernels' common RAM: REM0..REM2 serve as a 24-bit operand). Values are Q2.16 in 24-bit words,
; sign-extended into the 32-bit ACC for arithmetic (19-bit operands: sums and differences are exact in 32
; bits) and saturated to the model's 19-bit word (W_LP) by sat_lp where the model saturates. Sample indices
; are 16 bits; since(a, b) is their difference read as signed, sign-extended into ACC.

; ---- flags of AFLAGS (bank 1) through FSR -------------------------------------------------------------
SET_M           macro                   ; M = N - 1 - R3 (16 bits), the filter output's index
        movlw   LOW (R3 + 1)
        subwf   N_L, W
        movwf   M_L
        movf    N_H, W
        btfss   STATUS, C
        decf    N_H, W
        movwf   M_H
        endm
JAF_SET         macro   bit, label      ; goto label when AFLAGS.bit is set
        movlw   AFLAGS
        movwf   FSR
        btfsc   INDF, bit
        goto    label
        endm
JAF_CLR         macro   bit, label      ; goto label when AFLAGS.bit is clear
        movlw   AFLAGS
        movwf   FSR
        btfss   INDF, bit
        goto    label
        endm
AFSET           macro   bit
        movlw   AFLAGS
        movwf   FSR
        bsf     INDF, bit
        endm
AFCLR           macro   bit
        movlw   AFLAGS
        movwf   FSR
        bcf     INDF, bit
        endm
LDB             macro   var             ; W = a bank-1 byte
        movlw   var
        movwf   FSR
        movf    INDF, W
        endm
JNEG            macro   label           ; goto label when ACC < 0
        btfsc   ACC3, 7
        goto    label
        endm
JNNEG           macro   label           ; goto label when ACC >= 0
        btfss   ACC3, 7
        goto    label
        endm
LDK24           macro   k               ; ACC = the non-negative constant k
        movlw   LOW (k)
        movwf   ACC0
        movlw   HIGH (k)
        movwf   ACC1
        movlw   ((k) >> .16) & 0xFF
        movwf   ACC2
        clrf    ACC3
        endm
CALL_P1         macro   label           ; call a routine of program memory page 1 (steps_page1.asm)
        bsf     PCLATH, 3
        call    label
        bcf     PCLATH, 3
        endm
REMK24          macro   k               ; REM0..REM2 = the non-negative constant k
        movlw   LOW (k)
        movwf   REM0
        movlw   HIGH (k)
        movwf   REM1
        movlw   ((k) >> .16) & 0xFF
        movwf   REM2
        endm

; =====================================================================================================
; Step 4: a_v (AV) into the delay line, N += 1 (F_OLD from its bit 15 first), the scratch flush mark every
; FLUSH samples; once the run has 2 R3 + 1 samples (or is old), y3 at the line's centre, then step 5.
stage_fir:
        btfss   N_H, 7                  ; bit 15 of N: the run is old, N may wrap from now on
        goto    sf_line
        AFSET   AF_OLD
sf_line:
        LDB     LINE_POS                ; LINE[LINE_POS] = a_v
        movwf   FSR
        bcf     STATUS, C
        rlf     FSR, F
        movlw   LINE
        addwf   FSR, F
        movf    AV_L, W
        movwf   INDF
        incf    FSR, F
        movf    AV_H, W
        movwf   INDF
        LDB     LINE_POS                ; LINE_POS = (LINE_POS + 1) mod LINE_LEN (FSR -> LINE_POS)
        incf    INDF, F
        movf    INDF, W
        xorlw   LINE_LEN
        btfsc   STATUS, Z
        clrf    INDF
        incf    N_L, F                  ; N += 1 (16 bits, wraps)
        btfsc   STATUS, Z
        incf    N_H, F
        btfsc   STATUS, Z               ; N_U:N_T carry the count on (the step record's sample number)
        incf    N_U, F
        btfsc   STATUS, Z
        incf    N_T, F
        movf    N_L, W                  ; the run's (k+1) FLUSH-th sample: a page of a_v is due
        andlw   FLUSH - 1
        btfsc   STATUS, Z
        call    scratch_flush
        JAF_SET AF_OLD, sf_ready        ; young and N <= 2 R3 (n < 2 R3 before the increment): no output yet
        movf    N_H, W
        btfss   STATUS, Z
        goto    sf_ready
        movlw   LINE_LEN
        subwf   N_L, W
        btfss   STATUS, C
        return
sf_ready:
        LDB     LINE_POS                ; centre = (LINE_POS - 1 - R3) mod LINE_LEN = (LINE_POS + R3) mod LINE_LEN
        addlw   R3
        movwf   IDX_LO
        sublw   LINE_LEN - 1
        movlw   LINE_LEN
        btfss   STATUS, C
        subwf   IDX_LO, F
        movf    IDX_LO, W
        movwf   IDX_HI
        movlw   EE_W3                   ; the half-kernel, centre first, from the data EEPROM
        movwf   EE_PTR
        call    ee_next
        movwf   ARG0
        call    ee_next
        movwf   ARG1
        movf    IDX_LO, W
        call    line_load
        call    mul16s                  ; w0 a_centre (Q4.27, exact)
        call    sum_set_acc
        movlw   R3
        movwf   TAP
sf_tap:
        movf    IDX_LO, W               ; IDX_LO = centre - tap, IDX_HI = centre + tap (mod LINE_LEN)
        btfsc   STATUS, Z
        movlw   LINE_LEN
        movwf   IDX_LO
        decf    IDX_LO, F
        incf    IDX_HI, F
        movf    IDX_HI, W
        xorlw   LINE_LEN
        btfsc   STATUS, Z
        clrf    IDX_HI
        movf    IDX_HI, W               ; pair = a_+tap + a_-tap (16 bits, saturating)
        call    line_load
        movf    ACC0, W
        movwf   ARG0
        movf    ACC1, W
        movwf   ARG1
        movf    IDX_LO, W
        call    line_load
        CALL_P1 add16s
        call    ee_next                 ; w_tap pair, added to the sum (32 bits, saturating)
        movwf   ARG0
        call    ee_next
        movwf   ARG1
        call    mul16s
        call    sum_add_acc
        decfsz  TAP, F
        goto    sf_tap
        movf    SUM0, W                 ; y3 = the sum rounded half up to Q2.16, saturated to 19 bits
        movwf   ACC0
        movf    SUM1, W
        movwf   ACC1
        movf    SUM2, W
        movwf   ACC2
        movf    SUM3, W
        movwf   ACC3
        movlw   .11
        movwf   ARG0
        call    shr32r
        call    sat_lp
        movlw   Y3_0
        call    st24
        goto    stage_detect            ; tail call: the stack stays as deep as before

; scratch_flush: the delay line's newest FLUSH a_v go to the scratch ring (kernel.py step 4: one aligned
; page write of 2 FLUSH bytes): scr_write in page 2, which returns here with bank 0 and PCLATH = 0.
scratch_flush:
        movlw   HIGH scr_write
        movwf   PCLATH
        goto    scr_write

; line_load: ACC1:ACC0 = LINE[W]
line_load:
        movwf   FSR
        bcf     STATUS, C
        rlf     FSR, F
        movlw   LINE
        addwf   FSR, F
        movf    INDF, W
        movwf   ACC0
        incf    FSR, F
        movf    INDF, W
        movwf   ACC1
        return

; =====================================================================================================
; Step 5: the foot-flat detector at the filter output m = N - 1 - R3 (y3 in Y3).
stage_detect:
        SET_M                           ; m = N - 1 - R3 (16 bits)
        ; the pending foot-flat becomes final: m >= PEND + (MAX_STEP if weak else DIST), unless the peak
        ; being climbed lies within DIST of it, is higher, and m <= PEND + MAX_STEP (the look-ahead)
        JAF_CLR AF_PEND, sd_hyst
        movlw   M_L
        call    ld16
        movlw   PEND
        call    sub16
        LDB     DIST                    ; the limit: DIST, MAX_STEP for a weak one
        movwf   TMP2
        movlw   AFLAGS
        movwf   FSR
        movf    TMP2, W
        btfsc   INDF, AF_PEND_WEAK
        movlw   MAX_STEP
        call    acc_subw
        JNEG    sd_hyst
        JAF_CLR AF_LOOK_MAX, sd_final
        movlw   MXPOS
        call    ld16
        movlw   PEND
        call    sub16
        LDB     DIST
        call    acc_subw
        JNNEG   sd_final
        movlw   PEND_Y                  ; MX > PEND_Y
        call    ld24
        movlw   MX
        call    sub24
        JNNEG   sd_final
        movlw   M_L
        call    ld16
        movlw   PEND
        call    sub16
        movlw   MAX_STEP
        call    acc_subw
        movlw   1
        call    acc_subw
        JNEG    sd_hyst                 ; the look-ahead holds it
sd_final:
        call    finalise
        AFCLR   AF_PEND
sd_hyst:
        JAF_SET AF_OLD, sd_look         ; the run's first output (m = R3, young): MN = y
        movf    M_H, W
        btfss   STATUS, Z
        goto    sd_look
        movf    M_L, W
        xorlw   R3
        btfss   STATUS, Z
        goto    sd_look
        movlw   Y3_0
        call    ld24
        movlw   MN
        goto    st24
sd_look:
        JAF_CLR AF_LOOK_MAX, sd_trough
        movlw   MX                      ; climbing: y > MX, a new maximum
        call    ld24
        movlw   Y3_0
        call    sub24
        JNEG    set_mx_y
        call    prominence              ; y < sub(MX, prominence): the peak is confirmed
        movlw   REM0
        call    st24
        movlw   MX
        call    ld24
        movlw   REM0
        call    sub24
        call    sat_lp
        call    y_minus_acc
        JNEG    sd_confirm
#if STOP > 0
        REMK24  STOP                    ; y < sub(MX, STOP): a peak that rose fully and fell a little
        movlw   MX
        call    ld24
        movlw   REM0
        call    sub24
        call    sat_lp
        call    y_minus_acc
        btfsc   ACC3, 7
        call    stop_candidate
#endif
        return
sd_confirm:
        JAF_CLR AF_PEND_WEAK, sd_amp    ; a full foot-flat follows the weak one: it was no stop step
        AFCLR   AF_PEND
        AFCLR   AF_PEND_WEAK
sd_amp:
        movlw   MX                      ; the rise: sub(MX, MN)
        call    ld24
        movlw   MN
        call    sub24
        call    sat_lp
        JAF_CLR AF_AMP, sd_amp_set      ; the first amplitude: the rise itself
        movlw   AMP                     ; AMP = add(AMP, scale2(sub(rise, AMP), -AMP_SHIFT))
        call    sub24
        call    sat_lp
        movlw   AMP_SHIFT
        movwf   ARG0
        call    shr32r
        movlw   AMP
        call    add24
        call    sat_lp
sd_amp_set:
        movlw   AMP
        call    st24
        AFSET   AF_AMP
        call    confirmed
        AFCLR   AF_LOOK_MAX
        movlw   Y3_0                    ; looking for a trough: MN = MX = y, MXPOS = m
        call    ld24
        movlw   MN
        call    st24
        goto    set_mx_y
sd_trough:
        movlw   Y3_0                    ; y < MN: a new minimum (MX, MXPOS follow it)
        call    ld24
        movlw   MN
        call    sub24
        JNNEG   sd_rise
        movlw   Y3_0
        call    ld24
        movlw   MN
        call    st24
        goto    set_mx_y
sd_rise:
        call    prominence              ; y > add(MN, prominence): climbing a peak
        movlw   REM0
        call    st24
        movlw   MN
        call    ld24
        movlw   REM0
        call    add24
        call    sat_lp
        movlw   Y3_0
        call    sub24
        JNNEG   sd_weak
        AFSET   AF_LOOK_MAX
        JAF_CLR AF_PEND_WEAK, set_mx_y  ; not quiet after a weak peak: it was no stop step
        AFCLR   AF_PEND
        AFCLR   AF_PEND_WEAK
        goto    set_mx_y
sd_weak:
#if STOP > 0
        goto    weak_peak
#else
        return
#endif

; set_mx_y: MX = y, MXPOS = m
set_mx_y:
        movlw   Y3_0
        call    ld24
        movlw   MX
        call    st24
        movlw   M_L
        call    ld16
        movlw   MXPOS
        goto    st16

; y_minus_acc: ACC = y - ACC (REM0..2 = the old ACC): negative when y < ACC
y_minus_acc:
        movlw   REM0
        call    st24
        movlw   Y3_0
        call    ld24
        movlw   REM0
        goto    sub24

; prominence: ACC = the prominence in force (kernel._prominence): CAP until an amplitude is known, else
; FRAC AMP (AMP rounded to Q2.13, the product to Q2.16) clamped to DELTA .. CAP
prominence:
        JAF_CLR AF_AMP, pr_cap
#if CAP <= DELTA
        goto    pr_delta
#else
        movlw   AMP
        call    ld24
        movlw   3
        movwf   ARG0
        call    shr32r
        call    sat16
        movlw   LOW FRAC
        movwf   ARG0
        movlw   HIGH FRAC
        movwf   ARG1
        call    mul16s
        movlw   .11
        movwf   ARG0
        call    shr32r
        call    sat_lp
        movlw   REM0                    ; REM = scaled
        call    st24
        LDK24   CAP                     ; scaled > CAP: CAP
        movlw   REM0
        call    sub24
        JNEG    pr_cap
        LDK24   DELTA                   ; scaled > DELTA: scaled
        movlw   REM0
        call    sub24
        JNNEG   pr_delta
        movlw   REM0
        goto    ld24
#endif
pr_cap:
        LDK24   CAP
        return
pr_delta:
        LDK24   DELTA
        return

#if STOP > 0
; weak_peak (kernel._weak_peak), looking for a trough
weak_peak:
        movlw   MX                      ; y > MX: MX follows it
        call    ld24
        movlw   Y3_0
        call    sub24
        JNEG    set_mx_y
        REMK24  STOP                    ; y < sub(MX, STOP) and MX > add(MN, STOP): a weak peak
        movlw   MX
        call    ld24
        movlw   REM0
        call    sub24
        call    sat_lp
        call    y_minus_acc
        JNNEG   wp_done
        REMK24  STOP
        movlw   MN
        call    ld24
        movlw   REM0
        call    add24
        call    sat_lp
        movlw   MX
        call    sub24
        JNNEG   wp_done
        call    stop_candidate
        goto    set_mx_y
wp_done:
        return
#endif

; stop_candidate (kernel._stop_candidate): the weak peak at MXPOS becomes the pending foot-flat, marked
; weak, when FLAGS & (LAST, LAST_WEAK, PEND) = LAST and DIST <= since(MXPOS, LAST) <= min(3 DIST, MAX_STEP)
stop_candidate:
        movlw   AFLAGS
        movwf   FSR
        movf    INDF, W
        andlw   (1 << AF_LAST) | (1 << AF_LAST_WEAK) | (1 << AF_PEND)
        xorlw   1 << AF_LAST
        btfss   STATUS, Z
        return
        movlw   MXPOS
        call    ld16
        movlw   LAST
        call    sub16
        LDB     DIST
        call    acc_subw
        btfsc   ACC3, 7
        return
        LDB     DIST                    ; W = min(3 DIST, MAX_STEP) (MAX_STEP < 256)
        movwf   TMP2
        sublw   .85                     ; DIST > 85: 3 DIST > 255 >= MAX_STEP
        movlw   MAX_STEP
        btfss   STATUS, C
        goto    sc_limit
        movf    TMP2, W
        addwf   TMP2, W
        addwf   TMP2, W
        movwf   TMP2
        sublw   MAX_STEP
        movlw   MAX_STEP
        btfsc   STATUS, C
        movf    TMP2, W
sc_limit:
        movwf   TMP2
        movlw   MXPOS
        call    ld16
        movlw   LAST
        call    sub16
        movf    TMP2, W
        call    acc_subw
        movlw   1
        call    acc_subw
        btfss   ACC3, 7
        return
        call    set_pend
        AFSET   AF_PEND
        AFSET   AF_PEND_WEAK
        return

; set_pend: PEND = MXPOS, PEND_Y = MX; set_raw: RAW = MXPOS, RAW_Y = MX
set_pend:
        movlw   MXPOS
        call    ld16
        movlw   PEND
        call    st16
        movlw   MX
        call    ld24
        movlw   PEND_Y
        goto    st24
set_raw:
        movlw   MXPOS
        call    ld16
        movlw   RAW
        call    st16
        movlw   MX
        call    ld24
        movlw   RAW_Y
        goto    st24

; confirmed (kernel._confirmed): the peak p = MXPOS, yp = MX confirmed by the hysteresis, at m
confirmed:
        clrf    ACC0                    ; yp <= 0: no double support
        clrf    ACC1
        clrf    ACC2
        clrf    ACC3
        movlw   MX
        call    sub24
        JNNEG   cf_done
        JAF_CLR AF_RAW, cf_new_raw      ; the duration stream: peaks MIN_STEP apart
        movlw   MXPOS
        call    ld16
        movlw   RAW
        call    sub16
        movlw   MIN_STEP
        call    acc_subw
        JNNEG   cf_interval
        movlw   RAW_Y                   ; closer: the higher one stays
        call    ld24
        movlw   MX
        call    sub24
        btfsc   ACC3, 7
        call    set_raw
        goto    cf_candidate
cf_interval:
        movlw   MXPOS                   ; an interval up to MAX_STEP enters the durations ring
        call    ld16
        movlw   RAW
        call    sub16
        movlw   MAX_STEP
        call    acc_subw
        movlw   1
        call    acc_subw
        JNNEG   cf_new_raw
        movlw   MXPOS
        call    ld16
        movlw   RAW
        call    sub16
        LDB     DUR_POS                 ; DURS[DUR_POS] = the interval (a byte: <= MAX_STEP)
        addlw   DURS
        movwf   FSR
        movf    ACC0, W
        movwf   INDF
        LDB     DUR_POS                 ; DUR_POS = (DUR_POS + 1) mod N_MED
        incf    INDF, F
        movf    INDF, W
        xorlw   N_MED
        btfsc   STATUS, Z
        clrf    INDF
        LDB     N_DUR                   ; N_DUR = min(N_DUR + 1, N_MED)
        xorlw   N_MED
        btfss   STATUS, Z
        incf    INDF, F
        movlw   3                       ; three known: DIST from their median
        subwf   INDF, W
        btfsc   STATUS, C
        call    update_dist
cf_new_raw:
        call    set_raw
        AFSET   AF_RAW
cf_candidate:
        JAF_CLR AF_LAST, cf_pend        ; within DIST of a final foot-flat: not a candidate
        movlw   MXPOS
        call    ld16
        movlw   LAST
        call    sub16
        LDB     DIST
        call    acc_subw
        JNEG    cf_done
cf_pend:
        JAF_SET AF_PEND, cf_have
        call    set_pend
        AFSET   AF_PEND
        return
cf_have:
        movlw   MXPOS                   ; within DIST of the pending one: the higher stays
        call    ld16
        movlw   PEND
        call    sub16
        LDB     DIST
        call    acc_subw
        JNNEG   cf_final
        movlw   PEND_Y
        call    ld24
        movlw   MX
        call    sub24
        JNEG    set_pend
        return
cf_final:
        call    finalise                ; beyond DIST: the pending one is final, this one pending
        goto    set_pend
cf_done:
        return

; update_dist: DIST = minimum_distance(twice the median of DURS[0 .. N_DUR - 1])
update_dist:
        LDB     N_DUR
        movwf   IDX_HI                  ; n
        movwf   IDX_LO
        bcf     STATUS, C
        rrf     IDX_LO, F               ; n // 2
        btfss   IDX_HI, 0
        goto    upd_even
        movf    IDX_LO, W               ; odd: 2 d[n // 2]
        CALL_P1 select
        movwf   ARG0
        clrf    ARG1
        bcf     STATUS, C
        rlf     ARG0, F
        rlf     ARG1, F
        goto    set_dist
upd_even:
        movf    IDX_LO, W               ; even: d[n/2 - 1] + d[n/2]
        CALL_P1 select
        movwf   IDX_HI
        decf    IDX_LO, W
        CALL_P1 select
        movwf   ARG0
        clrf    ARG1
        movf    IDX_HI, W
        addwf   ARG0, F
        btfsc   STATUS, C
        incf    ARG1, F
        goto    set_dist

; set_dist: DIST = max(MIN_STEP, (FRACTION ARG + 1000) // 2000) (parameters.minimum_distance; ARG = twice
; the typical step, samples; the quotient fits a byte for FRACTION <= 1000 and ARG <= 510)
set_dist:
        movlw   LOW FRACTION
        movwf   ACC0
        movlw   HIGH FRACTION
        movwf   ACC1
        call    mul16u
        movlw   LOW .1000
        addwf   ACC0, F
        movlw   HIGH .1000
        btfsc   STATUS, C
        addlw   1
        addwf   ACC1, F
        btfss   STATUS, C
        goto    dist_div
        incf    ACC2, F
        btfsc   STATUS, Z
        incf    ACC3, F
dist_div:
        movlw   LOW .2000
        movwf   ARG0
        movlw   HIGH .2000
        movwf   ARG1
        call    div32u
        movlw   MIN_STEP
        subwf   ACC0, W
        movf    ACC0, W
        btfss   STATUS, C
        movlw   MIN_STEP
        movwf   TMP2
        movlw   DIST
        movwf   FSR
        movf    TMP2, W
        movwf   INDF
        return

; finalise (kernel._finalise at the final foot-flat e = PEND, newest output m): the call record (e, s = LAST,
; m, the flags the step reads: LAST valid, PEND weak, the run old; the harness compares it): e, s and m go
; straight to the step record's inputs E, S, FM (bank 3), the flags to CALL_FLAGS (written last), then the step
; record, step_record.asm's finalise in page 2 by a jump (fin_join): the caller's CALL is its return, so
; steps 4-5 and the step record share the stack levels (logger.asm: 8 of 8 with the interrupt's)
finalise:
        movlw   PEND                    ; e, s, m: the step record's inputs E, S, FM (bank 3, IRP = 1)
        call    ld16
        bsf     STATUS, IRP
        movlw   LOW CALL_E
        call    st16
        bcf     STATUS, IRP
        movlw   LAST
        call    ld16
        bsf     STATUS, IRP
        movlw   LOW CALL_S
        call    st16
        bcf     STATUS, IRP
        movlw   M_L
        call    ld16
        bsf     STATUS, IRP
        movlw   LOW CALL_M
        call    st16
        bcf     STATUS, IRP
        movlw   AFLAGS
        movwf   FSR
        movf    INDF, W
        andlw   (1 << AF_LAST) | (1 << AF_PEND_WEAK) | (1 << AF_OLD)
        movwf   TMP2
        movlw   CALL_FLAGS
        movwf   FSR
        movf    TMP2, W
        movwf   INDF
        movlw   HIGH fin_join           ; the step record (page 2): it returns to the caller with bank 0,
        movwf   PCLATH                  ; IRP = 0 and PCLATH = 0
        goto    fin_join

; step_flush (kernel.flush, at STOP): the pending foot-flat becomes final with the samples there are. When
; there is one (F_PEND) and the run has had a filter output (F_OLD or N > 2 R3), finalise at e = PEND and the
; newest output m = N - 1 - R3 (16 bits, as stage_detect computes it after the last sample's N += 1), then
; F_PEND cleared. Called by the main loop once every sample taken is processed: 1 level, finalise's CALL and
; the step record below it (4 levels with finalise's return): 5 of 8 with the interrupt's 2 (scr_write_w: 2).
step_flush:
        JAF_CLR AF_PEND, fl_done
        JAF_SET AF_OLD, fl_final
        movf    N_H, W
        btfss   STATUS, Z
        goto    fl_final
        movlw   LINE_LEN                ; young: N > 2 R3 <=> N - (2 R3 + 1) does not borrow
        subwf   N_L, W
        btfss   STATUS, C
        return
fl_final:
        movf    N_L, W                  ; the newest N mod FLUSH a_v are not in the scratch ring yet (the
        andlw   FLUSH - 1               ; model's newest are its delay line's): the step record reads them
        btfsc   STATUS, Z               ; there, so they go first (scr_write_w in page 1, which returns with
        goto    fl_m                    ; PCLATH = 0)
        bsf     PCLATH, 3
        call    scr_write_w
        bsf     FW_FLAGS, FWF_TAIL      ; written: fin_join does not write them again
fl_m:
        SET_M                           ; m = N - 1 - R3 (16 bits)
        call    finalise
        AFCLR   AF_PEND
fl_done:
        return

; reset_steps (START): steps 4-5's state cleared, DIST from the prior typical step
reset_steps:
        bcf     STATUS, IRP
        movlw   LINE
        movwf   FSR
rs_clear:
        clrf    INDF
        incf    FSR, F
        movf    FSR, W
        xorlw   RAM1_FW                 ; steps 4-5's state (not the header counters after it)
        btfss   STATUS, Z
        goto    rs_clear
        movlw   LOW PRIOR_TWICE
        movwf   ARG0
        movlw   HIGH PRIOR_TWICE
        movwf   ARG1
        goto    set_dist

; ---- multi-byte helpers: the operand's address in W (banks 0-1 or common RAM, through FSR) -----------
; ld24: ACC = the 24-bit word at W, sign-extended
ld24:
        movwf   FSR
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

; st24: the 24-bit word at W = ACC2:ACC1:ACC0
st24:
        movwf   FSR
        movf    ACC0, W
        movwf   INDF
        incf    FSR, F
        movf    ACC1, W
        movwf   INDF
        incf    FSR, F
        movf    ACC2, W
        movwf   INDF
        return

; sub24: ACC -= the 24-bit word at W, sign-extended (32 bits)
sub24:
        movwf   FSR
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
        clrf    TMP0                    ; the sign extension (CLRF, DECF leave C alone)
        btfsc   INDF, 7
        decf    TMP0, F
        movf    TMP0, W
        btfss   STATUS, C
        incfsz  TMP0, W
        subwf   ACC3, F
        return

; add24: ACC += the 24-bit word at W, sign-extended (32 bits)
add24:
        movwf   FSR
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
        clrf    TMP0
        btfsc   INDF, 7
        decf    TMP0, F
        movf    TMP0, W
        btfsc   STATUS, C
        incfsz  TMP0, W
        addwf   ACC3, F
        return

; sat_lp: ACC saturated to the FIR outputs' 19-bit word, -2^18 .. 2^18 - 1 (FLAG_SAT when clipped)
sat_lp:
        btfsc   ACC3, 7
        goto    sl_neg
        movf    ACC3, F
        btfss   STATUS, Z
        goto    sl_hi
        movlw   0xFC
        andwf   ACC2, W
        btfsc   STATUS, Z
        return
sl_hi:
        bsf     FLAGS, FLAG_SAT
        movlw   0xFF
        movwf   ACC0
        movwf   ACC1
        movlw   0x03
        movwf   ACC2
        clrf    ACC3
        return
sl_neg:
        comf    ACC3, W
        btfss   STATUS, Z
        goto    sl_lo
        movlw   0xFC
        andwf   ACC2, W
        xorlw   0xFC
        btfsc   STATUS, Z
        return
sl_lo:
        bsf     FLAGS, FLAG_SAT
        clrf    ACC0
        clrf    ACC1
        movlw   0xFC
        movwf   ACC2
        movlw   0xFF
        movwf   ACC3
        return

; ld16: ACC1:ACC0 = the 16-bit word at W
ld16:
        movwf   FSR
        movf    INDF, W
        movwf   ACC0
        incf    FSR, F
        movf    INDF, W
        movwf   ACC1
        return

; sub16: ACC = since(ACC1:ACC0, the 16-bit word at W): the 16-bit difference, sign-extended to 32 bits
sub16:
        movwf   FSR
        movf    INDF, W
        subwf   ACC0, F
        incf    FSR, F
        movf    INDF, W
        btfss   STATUS, C
        incfsz  INDF, W
        subwf   ACC1, F
        clrf    ACC2
        btfsc   ACC1, 7
        decf    ACC2, F
        movf    ACC2, W
        movwf   ACC3
        return

; st16: the 16-bit word at W = ACC1:ACC0
st16:
        movwf   FSR
        movf    ACC0, W
        movwf   INDF
        incf    FSR, F
        movf    ACC1, W
        movwf   INDF
        return

; acc_subw: ACC -= W (an unsigned byte), 32 bits
acc_subw:
        subwf   ACC0, F
        btfsc   STATUS, C
        return
        movlw   1
        subwf   ACC1, F
        btfsc   STATUS, C
        return
        subwf   ACC2, F
        btfsc   STATUS, C
        return
        subwf   ACC3, F
        return
