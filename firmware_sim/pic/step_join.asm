; The logger's joins to the step record, in page 1 (logger.asm): entered by a jump with PCLATH = 0x08 from
; page 0; the step record (page 2) and scr_write return to the caller there with bank 0, IRP = 0 and
; PCLATH = 0 (RETURN takes the whole address from the stack; PCLATH only matters to the next GOTO or CALL).

; fin_join (from steps.asm's finalise, bank 0): the header's steps_written counted, the step record's inputs from
; steps 4-5's state, then the step record itself (step_record.asm's finalise, finalise_p2 in page 2), whose
; RETURN ends the caller's CALL: E = e = PEND, FM = m = M (16-bit indices: finalise's call record wrote them);
;   REC+0..3 = the run's sample number of m: N - 1 - R3 in 32 bits
;   (N_T:N_U:N_H:N_L after step 4's increment); ALG_FLAGS, ALG_LAST are AFLAGS, LAST (logger_ram.inc), and the
;   saturation flag is the kernels' sticky FLAG_SAT, as the model's s_overflow.
; First the scratch ring's tail: the step record reads a_v up to e + SCR_AHEAD_E (M4's range: the 3 Hz FIR at
; e; the heel strike's band at e + hs_after) and, with a previous foot-flat s (AF_LAST), up to s + SCR_AHEAD_S
; (the toe-off's d10), none past N - 1; the ring has them up to the last flush, F0 - 1, F0 = N - N mod FLUSH.
; When that bound reaches F0, the newest N mod FLUSH a_v go to the ring first (scr_write_w, the write
; step_flush makes at STOP, which sets FWF_TAIL so that it is not made twice): otherwise the reader would get
; the ring's older bytes there. Only then: a write at every call would wear the ring's pages more.
fin_join:
        btfsc   FW_FLAGS, FWF_TAIL      ; STOP's step_flush wrote them
        goto    fj_inputs
        movf    N_L, W
        andlw   FLUSH - 1
        btfsc   STATUS, Z
        goto    fj_inputs               ; N a multiple of FLUSH: every a_v is on the ring
        bcf     STATUS, IRP
        movlw   PEND
        movwf   FSR
        movlw   SCR_AHEAD_E
        call    fj_reach
        btfss   TMP1, 7
        goto    fj_tail
        movlw   AFLAGS
        movwf   FSR
        btfss   INDF, AF_LAST
        goto    fj_inputs
        movlw   LAST
        movwf   FSR
        movlw   SCR_AHEAD_S
        call    fj_reach
        btfsc   TMP1, 7
        goto    fj_inputs
fj_tail:
        movf    N_L, W
        andlw   FLUSH - 1
        call    scr_write_w             ; returns in bank 0 with PCLATH = 0
        movlw   HIGH fin_join
        movwf   PCLATH
fj_inputs:
        bsf     STATUS, RP0             ; bank 1: the header's steps_written += 1, saturating at 2^32 - 1
        incfsz  STEPS_W, F              ; (Header.steps_written: the model counts each record it stores)
        goto    fj_counted
        incfsz  STEPS_W + 1, F
        goto    fj_counted
        incfsz  STEPS_W + 2, F
        goto    fj_counted
        incfsz  STEPS_W + 3, F
        goto    fj_counted
        movlw   0xFF                    ; it was 2^32 - 1: it stays there
        movwf   STEPS_W
        movwf   STEPS_W + 1
        movwf   STEPS_W + 2
        movwf   STEPS_W + 3
fj_counted:
        bcf     STATUS, RP0             ; bank 0
        movf    N_L, W                  ; ACC = N (32 bits) - (R3 + 1)
        movwf   ACC0
        movf    N_H, W
        movwf   ACC1
        movf    N_U, W
        movwf   ACC2
        movf    N_T, W
        movwf   ACC3
        movlw   R3 + 1
        subwf   ACC0, F
        btfsc   STATUS, C
        goto    fj_store
        movlw   1                       ; the borrow, on through the upper bytes
        subwf   ACC1, F
        btfss   STATUS, C
        subwf   ACC2, F
        btfss   STATUS, C
        subwf   ACC3, F
fj_store:
        bsf     STATUS, RP0             ; bank 3
        bsf     STATUS, RP1
        movf    ACC0, W
        movwf   REC
        movf    ACC1, W
        movwf   REC + 1
        movf    ACC2, W
        movwf   REC + 2
        movf    ACC3, W
        movwf   REC + 3
        movlw   HIGH finalise_p2
        movwf   PCLATH
        goto    finalise_p2

; fj_reach (bank 0, IRP = 0): FSR = a 16-bit index (bank 1), W = an offset -> TMP1:TMP0 = index + W - F0, F0 =
; N - N mod FLUSH the first sample not yet on the ring (16 bits: bit 7 of TMP1 clear when index + W >= F0)
fj_reach:
        addwf   INDF, W
        movwf   TMP0
        incf    FSR, F
        movf    INDF, W
        btfsc   STATUS, C
        addlw   1
        movwf   TMP1
        movf    N_L, W
        andlw   0x100 - FLUSH
        subwf   TMP0, F
        movf    N_H, W
        btfss   STATUS, C
        incf    N_H, W
        subwf   TMP1, F
        return

; scr_write (from steps.asm's scratch_flush, bank 0, after step 4's N += 1 with N a multiple of FLUSH): the
; delay line's newest FLUSH a_v, samples j = N - FLUSH .. N - 1, to the scratch ring at ring sample
; K + j (SCR_K, 16 bits; the run's sample f at (S + f) mod SCR_SAMPLES, S from the run's start page), byte
; 2 (K + j) of the ring's block, where finalise's reader (scr_open) looks for them: one page write (2 FLUSH
; bytes, aligned: FLUSH is a power of two that divides the ring's start, its length and half the EEPROM's
; page). A write that would start at the ring's end (ring sample SCR_SAMPLES) starts at 0 instead, and K goes
; down by SCR_SAMPLES: the cursor wraps with the ring, not with the 16-bit index. Then acknowledge polling:
; the EEPROM does not answer its control byte until its write cycle is over, so the step record's reads never
; meet a write in progress.
; scr_write_w (from steps.asm's step_flush at STOP): the same for the newest COUNT = W = N mod FLUSH a_v
; (1 .. FLUSH - 1), the start of the block the next flush would have written: a shorter write within the
; same page.
scr_write:
        movlw   LOW FLUSH
scr_write_w:
        movwf   COUNT                   ; COUNT = the a_v to write
        subwf   N_L, W                  ; ARG1:ARG0 = j = N - COUNT
        movwf   ARG0
        movf    N_H, W
        btfss   STATUS, C
        decf    N_H, W
        movwf   ARG1
        movf    SCR_K_L, W              ; ARG1:ARG0 = K + j, the ring sample
        addwf   ARG0, F
        movf    SCR_K_H, W
        btfsc   STATUS, C
        addlw   1
        addwf   ARG1, F
        movf    ARG0, F                 ; the ring's end (SCR_SAMPLES, a multiple of 256): on from ring sample 0
        btfss   STATUS, Z
        goto    sw_place
        movf    ARG1, W
        xorlw   HIGH SCR_SAMPLES
        btfss   STATUS, Z
        goto    sw_place
        clrf    ARG1
        movlw   HIGH SCR_SAMPLES
        subwf   SCR_K_H, F              ; K -= SCR_SAMPLES
sw_place:
        bcf     STATUS, C               ; TMP1:TMP0 = 2 (K + j), the byte in the ring's block
        rlf     ARG0, W
        movwf   TMP0
        rlf     ARG1, W
        movwf   TMP1
        movf    COUNT, W                ; j's place in the line: (LINE_POS - COUNT) mod LINE_LEN
        sublw   LINE_LEN
        bsf     STATUS, RP0
        addwf   LINE_POS, W
        bcf     STATUS, RP0
        movwf   ARG0
        sublw   LINE_LEN - 1
        movlw   LINE_LEN
        btfss   STATUS, C
        subwf   ARG0, F
        bcf     STATUS, C               ; FSR = LINE + 2 (that place), IRP = 0
        rlf     ARG0, W
        addlw   LINE
        movwf   FSR
        bcf     STATUS, IRP
        I2C_CMD SEN
        movlw   SCR_CONTROL
        call    sw_tx
        movf    TMP1, W
        call    sw_tx
        movf    TMP0, W
        call    sw_tx
        bcf     STATUS, C               ; 2 COUNT bytes
        rlf     COUNT, F
sw_byte:
        movf    INDF, W
        call    sw_tx
        incf    FSR, F
        movf    FSR, W
        xorlw   LINE + 2 * LINE_LEN     ; the line's end: on from its start
        movlw   LINE
        btfsc   STATUS, Z
        movwf   FSR
        decfsz  COUNT, F
        goto    sw_byte
        I2C_CMD PEN
sw_poll:
        I2C_CMD SEN
        movlw   SCR_CONTROL
        call    sw_tx
        bsf     STATUS, RP0
        btfss   SSPCON2, ACKSTAT        ; acknowledged: the write cycle is over
        goto    sw_done
        I2C_CMD PEN
        goto    sw_poll
sw_done:
        I2C_CMD PEN
        clrf    STATUS
        clrf    PCLATH
        return

; sw_tx: send W, wait for the acknowledge slot (step_record.asm's i2c_tx, for page 1)
sw_tx:
        bcf     STATUS, RP0
        bcf     STATUS, RP1
        movwf   SSPBUF
        I2C_WAIT
        return
