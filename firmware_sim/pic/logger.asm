; The logger's per-sample firmware path: the sampling interrupt (timer, three ADC channels, P32 packing
; into the page buffer, page handoff) and the main loop's first stages of the on-line step algorithm
; (calibration: codes -> g in Q2.13, kernel.py step 1; gravity, two exponential means, step 2; the
; vertical acceleration a_v = (f.g - |g|^2) / |g|, step 3). RAM map: logger_ram.inc. Maths: the kernels
; (registers.inc, CONVENTION.md).
;
; Steps 4-5 (kernel.py): a_v into the delay line, the centred 3 Hz FIR y3 (stage_fir), the foot-flat
; detector (stage_detect: hysteresis, prominence, confirmed peaks, durations and minimum distance, the
; pending foot-flat, the stop rule); each final foot-flat calls finalise, which for now leaves its
; arguments in a call record (the step record is step_record.asm's). The scratch ring's page write is the
; driver's: scratch_flush marks it.
;
; Assembled by gpsim_logger.py with these symbols (gpasm -D):
;   CCP_PERIOD      Timer1 counts per sample (CCPR1; compare mode, special event trigger resets Timer1)
;   T1_SETUP        T1CON: prescaler bits | TMR1ON
;   ACQ_LOOPS       acquisition delay: 3 cycles a loop (>= the ADXL202's 32 kOhm source's TACQ)
;   FIRST_SAMPLE_L, FIRST_SAMPLE_H, FIRST_SAMPLE_U, FIRST_SAMPLE_T, PAGE_START
;                   the sample number the run (a START) begins at (the header's samples_written at START, 32
;                   bits), and its word's place in the page buffer
;   OVERWRITE, STEPS_WRITTEN
;                   the run's mode (the header's OVERWRITE flag: 1 ring, 0 stop when full) and the header's
;                   steps_written at START (32 bits); the header counters are logger_ram.inc's
;   SCR_K0          the scratch ring's offset at START (SCR_K, logger_ram.inc): the ring sample of the run's
;                   first sample (the first of the page the run's first sample number points to, kernel.py
;                   scratch_ring_sample), minus the kernel's N at START, modulo 2^16
;   SCR_SAMPLES     the scratch ring's samples (kernel.py SCRATCH_RING_SAMPLES: 32,512)
;   G_SHIFT         the gravity means' final shift (kernel CI G_SHIFT: 6 at 50 Hz)
;   G_MIN           the smallest |g| that gives an a_v (kernel CV G_MIN, Q2.13: 0.2 g = 1638)
;   R3, N_MED, MIN_STEP, MAX_STEP, FRACTION, AMP_SHIFT, PRIOR_TWICE, FLUSH
;                   the kernel's CI slots of the same names (samples; FRACTION out of 1000)
;   DELTA, CAP, FRAC, STOP
;                   the kernel's CV slots (prominence floor and cap, Q2.16; fraction, Q1.14; stop, Q2.16)
;   SCR_AHEAD_E, SCR_AHEAD_S
;                   how far past e and past s the step record reads a_v (kernel.py scratch_reads_ahead: 9, 19 at
;                   50 Hz): fin_join writes the ring's tail first when they reach past its last flush
; The calibration and the FIR weights are read from the data EEPROM (EE_CAL, EE_W3 in logger_ram.inc) where
; they are used, as the model charges them; the harness assembles the configuration into it (config.inc, DE).
; The test build (TEST_BUILD defined) also takes N_SAMPLES (< 65,536): after that many samples the interrupt
; stops the timer and sets FWF_STOP (the production build's STOP command, which the UART handler still leaves
; to the model), and the main loop, once it has caught up, finalises the pending step (step_flush) and ends at
; harness_done; and START_N: the kernel's N at START (0; otherwise the run
; is taken to be START_N samples old, its gravity warm-up over: WARM = G_SHIFT; the index-wrap tests
; start near 2^15 and 2^16 instead of simulating 65,536 samples first). Both builds convert the real ADC inputs AN0-AN2 (the harness
; drives them with gpsim's analog stimuli) and take the marker button on RB0/INT.
        list    p=16f877
        #include <p16f877.inc>
        #include "registers.inc"
        #include "logger_ram.inc"
; the step record's RAM (step_record_ram.inc: the tails of banks 2 and 3, the kernels' common RAM between
; their calls, and stage 3's |g|^2 in bank 0) on the algorithm state that steps 4-5 own
ALG_FLAGS       equ     AFLAGS          ; state.py FLAGS and LAST, read and updated by finalise
ALG_LAST_L      equ     LAST
ALG_LAST_H      equ     LAST + 1
STEP_CFG_EE     equ     0x30            ; the step configuration in the data EEPROM, after the calibration's
        #include "step_record_ram.inc"
        __CONFIG _HS_OSC & _WDT_OFF & _PWRTE_ON & _LVP_OFF & _BODEN_OFF & _CP_OFF

ADC_SETUP       equ     0x82            ; ADCON1: right-justified, AN0-AN4 analog, Vref = VDD/VSS
ADC_CH0         equ     0x81            ; ADCON0: Fosc/32 (TAD 1.74 us at 18.432 MHz), channel 0, ADON

; NEXT_WORD: W = the FSR after a word's last byte -> the FSR of the next word (the bank 2 half, then the
; bank 3 half, then the page again). In line and branch-free (6 cycles): the interrupt stays 2 stack levels deep.
NEXT_WORD       macro
        xorlw   PAGE_A_END
        btfsc   STATUS, Z
        movlw   PAGE_B ^ PAGE_A_END     ; the end of words 0-15: word 16
        xorlw   PAGE_A_END ^ PAGE_B_END
        btfsc   STATUS, Z
        movlw   PAGE_A ^ PAGE_B_END     ; the end of word 31: word 0
        xorlw   PAGE_B_END
        endm

; PAGE_FSR: FSR (IRP = 1) = the page-buffer word of slot w = SAMPLE_L mod 32 (the sample the interrupt takes):
; 0x10 + 4 w, words 16-31 at 0x90 + 4 (w - 16) (logger_ram.inc PAGE_A, PAGE_B). Branch-free (11 cycles).
PAGE_FSR        macro
        movf    SAMPLE_L, W
        andlw   0x1F
        movwf   FSR
        addwf   FSR, F                  ; 2 w
        movf    FSR, W
        addwf   FSR, F                  ; 4 w
        movlw   PAGE_A
        btfsc   FSR, 6                  ; w >= 16
        movlw   PAGE_B - 0x40
        addwf   FSR, F
        bsf     STATUS, IRP
        endm

        org     0
        goto    start

; =====================================================================================================
; The sampling interrupt: CCP1 compare (Timer1 reset by the special event trigger) once per sample period;
; INT (RB0) is the marker button. Context: W in W_TEMP (common RAM), STATUS, PCLATH, FSR in bank 0.
        org     4
isr:
        movwf   W_TEMP
        swapf   STATUS, W
        clrf    STATUS                  ; bank 0, IRP = 0
        movwf   STATUS_TEMP
        movf    PCLATH, W
        movwf   PCLATH_TEMP
        clrf    PCLATH
        movf    FSR, W
        movwf   FSR_TEMP
        btfss   INTCON, INTF
        goto    isr_timer
        bcf     INTCON, INTF            ; the marker button: flag the next sample
        bsf     FW_FLAGS, FWF_MARK
isr_timer:
        btfss   PIR1, CCP1IF
        goto    isr_exit
        bcf     PIR1, CCP1IF
        PAGE_FSR                        ; FSR (IRP = 1) = this sample's word: the slot SAMPLE_L mod 32
        movlw   ADC_CH0                 ; x: byte 0 = x bits 0-7; T_H = x bits 8-9
        call    adc_convert
        movwf   INDF
        incf    FSR, F
        movf    ADRESH, W
        movwf   T_H
        movlw   ADC_CH0 | (1 << 3)      ; y: byte 1 = x bits 8-9, y bits 0-5; T_H = y bits 6-9
        call    adc_convert
        movwf   T_L                     ; T_L = y bits 5-0, -, 7 after two rotates; C = y bit 6
        rlf     T_L, F
        rlf     T_L, F
        movf    T_L, W
        andlw   0xFC
        iorwf   T_H, W
        movwf   INDF
        incf    FSR, F
        movf    ADRESH, W               ; T_H = y9 y8, then y7 and y6 rotated in below them
        movwf   T_H
        rrf     T_L, F                  ; C = y bit 7 (T_L bit 7 = y bit 6)
        rlf     T_H, F
        rlf     T_L, F                  ; C = y bit 6
        rlf     T_H, F
        movlw   ADC_CH0 | (2 << 3)      ; z: byte 2 = y bits 6-9, z bits 0-3; byte 3 = z bits 4-9, S, M
        call    adc_convert
        movwf   T_L
        swapf   T_L, W
        andlw   0xF0
        iorwf   T_H, W
        movwf   INDF
        incf    FSR, F
        swapf   T_L, W
        andlw   0x0F
        movwf   T_L
        swapf   ADRESH, W
        iorwf   T_L, F
        btfsc   FW_FLAGS, FWF_SESSION
        bsf     T_L, 6
        btfsc   FW_FLAGS, FWF_MARK
        bsf     T_L, 7
        movf    T_L, W
        movwf   INDF
        bcf     STATUS, IRP
        bcf     FW_FLAGS, FWF_SESSION
        bcf     FW_FLAGS, FWF_MARK
        incf    SAMPLE_L, F             ; the header's samples_written (write_index: bits 0-15)
        btfsc   STATUS, Z
        incf    SAMPLE_H, F
        btfsc   STATUS, Z
        call    sample_wrap             ; bits 0-15 wrapped (every 65,536 samples)
        movf    SAMPLE_L, W
        andlw   0x1F
        btfsc   STATUS, Z
        bsf     FW_FLAGS, FWF_PAGE_FULL ; the page's last word: the I2C driver (the model's) writes the page
        incf    PENDING, F              ; hand the sample to the main loop
        movlw   .33
        subwf   PENDING, W
        btfsc   STATUS, C
        bsf     FW_FLAGS, FWF_OVERRUN   ; PENDING > 32: the main loop lost a sample
#ifdef TEST_BUILD
        movf    SAMPLE_L, W             ; N_SAMPLES taken (SAMPLE at FIRST_SAMPLE + N_SAMPLES): no more samples
        xorlw   LOW (FIRST_SAMPLE_L + (FIRST_SAMPLE_H << 8) + N_SAMPLES)
        btfss   STATUS, Z
        goto    isr_exit
        movf    SAMPLE_H, W
        xorlw   HIGH (FIRST_SAMPLE_L + (FIRST_SAMPLE_H << 8) + N_SAMPLES)
        btfss   STATUS, Z
        goto    isr_exit
        bsf     STATUS, RP0             ; N_SAMPLES taken: no more samples, STOP (the UART handler's STOP
        bcf     PIE1, CCP1IE            ; command in the production build, still the model's)
        bcf     STATUS, RP0
        bsf     FW_FLAGS, FWF_STOP
#endif
isr_exit:
        movf    FSR_TEMP, W
        movwf   FSR
        movf    PCLATH_TEMP, W
        movwf   PCLATH
        swapf   STATUS_TEMP, W
        movwf   STATUS
        swapf   W_TEMP, F
        swapf   W_TEMP, W
        retfie

; adc_convert: select the channel (W = ADCON0), wait the acquisition time, convert.
;   out: W = ADRESL (bank 0 selected again), ADRESH holds the high bits
adc_convert:
        movwf   ADCON0
        movlw   ACQ_LOOPS
        movwf   T_L
acq_wait:
        decfsz  T_L, F
        goto    acq_wait
        bsf     ADCON0, GO
adc_busy:
        btfsc   ADCON0, GO
        goto    adc_busy
        bsf     STATUS, RP0
        movf    ADRESL, W
        bcf     STATUS, RP0
        return

; sample_wrap (the interrupt, bank 0): samples_written reached a multiple of 2^16, the capacity (write_index
; wrapped to slot 0): bits 16-31 (bank 1) += 1, saturating at 2^32 - 1 (FWF_SW_SAT; SAMPLE_L/H go on as
; write_index, as the model's header keeps counting it). The memory is now full: in ring mode (FWF_OVERWRITE)
; the header's WRAPPED holds (it is samples_written >= capacity); otherwise the run stops here (the header's
; FULL_STOPPED, Ring.append: the sample that fills the memory is the last one), as the test build's stop.
sample_wrap:
        bsf     STATUS, RP0             ; bank 1
        incf    SAMPLE_U, F
        btfsc   STATUS, Z
        incf    SAMPLE_T, F
        btfss   STATUS, Z
        goto    sw_full
        decf    SAMPLE_U, F             ; bits 16-31 were 0xFFFF: samples_written stays at 2^32 - 1
        decf    SAMPLE_T, F
        bcf     STATUS, RP0
        bsf     FW_FLAGS, FWF_SW_SAT
sw_full:
        bcf     STATUS, RP0             ; bank 0
        btfsc   FW_FLAGS, FWF_OVERWRITE
        return
        bsf     FW_FLAGS, FWF_STOP      ; stop when full: no more samples, STOP
        bsf     STATUS, RP0
        bcf     PIE1, CCP1IE
        bcf     STATUS, RP0
        return

; =====================================================================================================
start:
        clrf    STATUS
        clrf    FLAGS
        clrf    FW_FLAGS
        clrf    PENDING
        movlw   FIRST_SAMPLE_L
        movwf   SAMPLE_L
        movlw   FIRST_SAMPLE_H
        movwf   SAMPLE_H
        movlw   PAGE_START
        movwf   ALG_PTR
        bsf     FW_FLAGS, FWF_SESSION
    if OVERWRITE
        bsf     FW_FLAGS, FWF_OVERWRITE
    endif
        bsf     STATUS, RP0             ; bank 1: the header's counters at START
        movlw   FIRST_SAMPLE_U
        movwf   SAMPLE_U
        movlw   FIRST_SAMPLE_T
        movwf   SAMPLE_T
        movlw   STEPS_WRITTEN & 0xFF
        movwf   STEPS_W
        movlw   (STEPS_WRITTEN >> .8) & 0xFF
        movwf   STEPS_W + 1
        movlw   (STEPS_WRITTEN >> .16) & 0xFF
        movwf   STEPS_W + 2
        movlw   (STEPS_WRITTEN >> .24) & 0xFF
        movwf   STEPS_W + 3
        bcf     STATUS, RP0
        call    reset_gravity           ; START: a fresh state
        call    reset_steps
#ifdef TEST_BUILD
#if START_N
        movlw   LOW START_N             ; a run START_N samples old (the index-wrap tests)
        movwf   N_L
        movlw   HIGH START_N
        movwf   N_H
        movlw   G_SHIFT
        movwf   WARM
#endif
#endif
        movlw   LOW SCR_K0              ; the scratch ring's offset at START (logger_ram.inc SCR_K)
        movwf   SCR_K_L
        movlw   HIGH SCR_K0
        movwf   SCR_K_H
        bsf     STATUS, RP0             ; bank 1
        movlw   ADC_SETUP
        movwf   ADCON1
        bsf     TRISB, 0                ; RB0/INT: the marker button
        bsf     PIE1, CCP1IE
        bsf     TRISC, 3                ; the MSSP: I2C master, 419 kHz (SSPADD = 10 at 18.432 MHz): the
        bsf     TRISC, 4                ; scratch ring's EEPROM (RC3 SCL, RC4 SDA)
        movlw   .10
        movwf   SSPADD
        clrf    SSPSTAT
        bcf     STATUS, RP0
        movlw   0x28
        movwf   SSPCON
        movlw   ADC_CH0
        movwf   ADCON0
        clrf    TMR1L
        clrf    TMR1H
        movlw   LOW CCP_PERIOD
        movwf   CCPR1L
        movlw   HIGH CCP_PERIOD
        movwf   CCPR1H
        movlw   0x0B                    ; CCP1: compare, special event trigger (resets Timer1)
        movwf   CCP1CON
        movlw   T1_SETUP
        movwf   T1CON
        clrf    PIR1
        bsf     INTCON, INTE
        bsf     INTCON, PEIE
        bsf     INTCON, GIE

; The main loop: the on-line algorithm on each sample the interrupt handed over, oldest first, read back
; from the page buffer (it may fall up to 32 samples behind).
main_loop:
        btfss   FW_FLAGS, FWF_STOP      ; STOP (the sampling interrupt is off) and every sample processed:
        goto    main_pending            ; the run ends (FWF_STOP first: PENDING cannot grow after it)
        movf    PENDING, W
        btfsc   STATUS, Z
        goto    main_stop
main_pending:
        movf    PENDING, W
        btfss   STATUS, Z
        goto    main_sample
        goto    main_loop
main_sample:
        call    read_word
        call    stage_calibrate
        call    stage_gravity
        call    stage_av
        call    stage_fir               ; step 4, and step 5 (stage_detect) once the filter has an output
        decf    PENDING, F
        goto    main_loop

; STOP (kernel.flush, the model's Device.stop_logging): the pending foot-flat becomes the run's last step record
main_stop:
        call    step_flush
        bcf     FW_FLAGS, FWF_STOP
        bcf     FW_FLAGS, FWF_TAIL
#ifdef TEST_BUILD
harness_done:
        goto    harness_done
#else
        goto    main_loop               ; idle until the next START (the UART handler's, still the model's)
#endif

; read_word: B3:B0 = the word at ALG_PTR; advance ALG_PTR
read_word:
        movf    ALG_PTR, W
        movwf   FSR
        bsf     STATUS, IRP
        movf    INDF, W
        movwf   B0
        incf    FSR, F
        movf    INDF, W
        movwf   B1
        incf    FSR, F
        movf    INDF, W
        movwf   B2
        incf    FSR, F
        movf    INDF, W
        movwf   B3
        incf    FSR, F
        bcf     STATUS, IRP
        movf    FSR, W
        NEXT_WORD
        movwf   ALG_PTR
        return

; =====================================================================================================
; Stage 1, calibration (kernel.py step 1): c = (code << 5) - offset (Q10.5, saturating), then per axis
; f = sat16(shr32r(sat32(m0 c0 + m1 c1 + m2 c2), CAL_SHIFT)) in Q2.13 g.
stage_calibrate:
        movf    B1, W                   ; x << 5 = ((B1 & 3):B0) << 5
        andlw   0x03
        movwf   C0H
        movf    B0, W
        movwf   C0L
        movlw   5
        call    shl_c0
        movf    B2, W                   ; y << 5 = ((B2 & 0x0F):(B1 & 0xFC)) << 3
        andlw   0x0F
        movwf   C1H
        movf    B1, W
        andlw   0xFC
        movwf   C1L
        movlw   3
        call    shl_c1
        movf    B3, W                   ; z << 5 = ((B3 & 0x3F):(B2 & 0xF0)) << 1
        andlw   0x3F
        movwf   C2H
        movf    B2, W
        andlw   0xF0
        movwf   C2L
        movlw   1
        call    shl_c2
        movlw   EE_CAL                  ; the offsets, then the matrix rows, in the EEPROM's order
        movwf   EE_PTR
        movlw   C0L
        call    sub_offset
        movlw   C1L
        call    sub_offset
        movlw   C2L
        call    sub_offset
        call    cal_row
        movf    ACC0, W
        movwf   FX_L
        movf    ACC1, W
        movwf   FX_H
        call    cal_row
        movf    ACC0, W
        movwf   FY_L
        movf    ACC1, W
        movwf   FY_H
        call    cal_row
        movf    ACC0, W
        movwf   FZ_L
        movf    ACC1, W
        movwf   FZ_H
        return

; shl_c0/1/2: C_H:C_L <<= W (W >= 1; the codes' top bits are 0, so nothing is lost)
shl_c0:
        movwf   COUNT
shl_c0_bit:
        bcf     STATUS, C
        rlf     C0L, F
        rlf     C0H, F
        decfsz  COUNT, F
        goto    shl_c0_bit
        return
shl_c1:
        movwf   COUNT
shl_c1_bit:
        bcf     STATUS, C
        rlf     C1L, F
        rlf     C1H, F
        decfsz  COUNT, F
        goto    shl_c1_bit
        return
shl_c2:
        movwf   COUNT
shl_c2_bit:
        bcf     STATUS, C
        rlf     C2L, F
        rlf     C2H, F
        decfsz  COUNT, F
        goto    shl_c2_bit
        return

; sub_offset: the int16 at bank 0 address W -= the next int16 of the EEPROM (EE_PTR), saturating
sub_offset:
        movwf   TMP2                    ; TMP2 = address of c
        call    ee_next                 ; ARG = offset
        movwf   ARG0
        call    ee_next
        movwf   ARG1
        movf    TMP2, W
        movwf   FSR                     ; FSR -> c (bank 0)
        movf    INDF, W
        movwf   ACC0
        incf    FSR, F
        movf    INDF, W
        movwf   ACC1
        xorwf   ARG1, W                 ; SGN_T bit 7: the operands' signs differ
        movwf   SGN_T
        movf    ARG0, W                 ; ACC1:ACC0 -= ARG1:ARG0
        subwf   ACC0, F
        movf    ARG1, W
        btfss   STATUS, C
        incfsz  ARG1, W
        subwf   ACC1, F
        btfss   SGN_T, 7
        goto    so_store                ; same signs: no overflow
        movf    ACC1, W                 ; overflow when the result's sign differs from c's
        xorwf   INDF, W
        andlw   0x80
        btfsc   STATUS, Z
        goto    so_store
        bsf     FLAGS, FLAG_SAT
        movlw   0xFF                    ; c >= 0: 0x7FFF; c < 0: 0x8000
        movwf   ACC0
        movlw   0x7F
        movwf   ACC1
        btfss   INDF, 7
        goto    so_store
        clrf    ACC0
        movlw   0x80
        movwf   ACC1
so_store:
        movf    ACC1, W
        movwf   INDF
        decf    FSR, F
        movf    ACC0, W
        movwf   INDF
        return

; cal_row: ACC1:ACC0 = the row of mantissas at EE_PTR applied to C0..C2, rounded to Q2.13
cal_row:
        call    load_mantissa
        movf    C0L, W
        movwf   ARG0
        movf    C0H, W
        movwf   ARG1
        call    mul16s
        movf    ACC0, W                 ; SUM = m0 c0
        movwf   SUM0
        movf    ACC1, W
        movwf   SUM1
        movf    ACC2, W
        movwf   SUM2
        movf    ACC3, W
        movwf   SUM3
        call    load_mantissa
        movf    C1L, W
        movwf   ARG0
        movf    C1H, W
        movwf   ARG1
        call    mul16s
        call    sum_add_acc
        call    load_mantissa
        movf    C2L, W
        movwf   ARG0
        movf    C2H, W
        movwf   ARG1
        call    mul16s
        call    sum_add_acc
        movf    SUM0, W                 ; ACC = SUM >> CAL_SHIFT (half up), saturated to 16 bits
        movwf   ACC0
        movf    SUM1, W
        movwf   ACC1
        movf    SUM2, W
        movwf   ACC2
        movf    SUM3, W
        movwf   ACC3
        movlw   EE_CAL_SHIFT
        call    ee_read
        movwf   ARG0
        call    shr32r
        goto    sat16                   ; tail call

; load_mantissa: ACC1:ACC0 = the next int16 of the EEPROM (EE_PTR += 2)
load_mantissa:
        call    ee_next
        movwf   ACC0
        call    ee_next
        movwf   ACC1
        return

; ee_next: W = the data-EEPROM byte at EE_PTR, EE_PTR += 1; ee_read: W = the byte at address W.
; Called and returning in bank 0 (FSR, IRP untouched).
ee_next:
        movf    EE_PTR, W
        incf    EE_PTR, F
ee_read:
        bsf     STATUS, RP1             ; bank 2
        movwf   EEADR
        bsf     STATUS, RP0             ; bank 3
        bcf     EECON1, EEPGD
        bsf     EECON1, RD
        bcf     STATUS, RP0             ; bank 2
        movf    EEDATA, W
        bcf     STATUS, RP1             ; bank 0
        return

; sum_add_acc: SUM = SUM + ACC, saturated to a signed 32-bit word (FLAG_SAT when clipped)
sum_add_acc:
        movf    SUM3, W
        xorwf   ACC3, W
        movwf   SGN_T                   ; bit 7: the signs differ (no overflow possible)
        movf    ACC0, W
        addwf   SUM0, F
        movf    ACC1, W
        btfsc   STATUS, C
        incfsz  ACC1, W
        addwf   SUM1, F
        movf    ACC2, W
        btfsc   STATUS, C
        incfsz  ACC2, W
        addwf   SUM2, F
        movf    ACC3, W
        btfsc   STATUS, C
        incfsz  ACC3, W
        addwf   SUM3, F
        btfsc   SGN_T, 7
        return
        movf    SUM3, W                 ; same signs: overflow when the sum's sign differs
        xorwf   ACC3, W
        andlw   0x80
        btfsc   STATUS, Z
        return
        bsf     FLAGS, FLAG_SAT
        movlw   0xFF
        movwf   SUM0
        movwf   SUM1
        movwf   SUM2
        movlw   0x7F
        movwf   SUM3
        btfss   ACC3, 7
        return
        clrf    SUM0                    ; negative: -2^31
        clrf    SUM1
        clrf    SUM2
        movlw   0x80
        movwf   SUM3
        return

; =====================================================================================================
; Stage 2, gravity (kernel.py step 2): per axis G1 += (f << 16 - G1) >> WARM, G2 += (G1 - G2) >> WARM (32 bits,
; saturating, the shifts rounding half up); WARM grows from 0 to G_SHIFT as the run reaches 2, 4, 8 ...
; samples (the running mean while the run is young).
GRAV_AXIS       macro   f_lo, f_hi, g1, g2
        clrf    ACC0                    ; ACC = f in Q2.29: the Q2.13 word is the top half
        clrf    ACC1
        movf    f_lo, W
        movwf   ACC2
        movf    f_hi, W
        movwf   ACC3
        movlw   g1
        movwf   FSR
        call    acc_sub_fsr             ; f - G1
        movf    WARM, W
        movwf   ARG0
        call    shr32r
        call    fsr_add_acc             ; G1 += ...
        call    acc_load_fsr            ; ACC = G1
        movlw   g2
        movwf   FSR
        call    acc_sub_fsr             ; G1 - G2
        movf    WARM, W
        movwf   ARG0
        call    shr32r
        call    fsr_add_acc             ; G2 += ...
        endm

stage_gravity:
        movlw   G_SHIFT
        xorwf   WARM, W
        btfsc   STATUS, Z
        goto    sg_axes                 ; warmed up: the count is no longer needed
        movf    WARM, W                 ; ARG = 2 << WARM, where WARM grows next (WARM < G_SHIFT here)
        movwf   COUNT
        movlw   2
        movwf   ARG0
        clrf    ARG1
        incf    COUNT, F
sg_thr:
        decfsz  COUNT, F
        goto    sg_shift
        goto    sg_cmp
sg_shift:
        bcf     STATUS, C
        rlf     ARG0, F
        rlf     ARG1, F
        goto    sg_thr
sg_cmp:
        movf    N_L, W                  ; n + 1 (N counts the run's samples before this one)
        movwf   ACC0
        movf    N_H, W
        movwf   ACC1
        incf    ACC0, F
        btfsc   STATUS, Z
        incf    ACC1, F
        movf    ACC0, W
        xorwf   ARG0, W
        btfss   STATUS, Z
        goto    sg_axes
        movf    ACC1, W
        xorwf   ARG1, W
        btfss   STATUS, Z
        goto    sg_axes
        incf    WARM, F                 ; n + 1 = 2 << WARM: one more bit of shift
sg_axes:
        bcf     STATUS, IRP
        GRAV_AXIS FX_L, FX_H, G1X, G2X
        GRAV_AXIS FY_L, FY_H, G1Y, G2Y
        GRAV_AXIS FZ_L, FZ_H, G1Z, G2Z
        return

; reset_gravity: G1 = G2 = 0, WARM = 0, N = 0 (its 32 bits)
reset_gravity:
        movlw   G1X
        movwf   FSR
        bcf     STATUS, IRP
rg_clear:
        clrf    INDF
        incf    FSR, F
        movf    FSR, W
        xorlw   N_T + 1
        btfss   STATUS, Z
        goto    rg_clear
        return

; acc_load_fsr: ACC = the int32 at FSR (bank 0); FSR unchanged
acc_load_fsr:
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
        movlw   3
        subwf   FSR, F
        return

; acc_sub_fsr: ACC = ACC - the int32 at FSR, saturated to 32 bits (FLAG_SAT when clipped); FSR unchanged
acc_sub_fsr:
        movlw   3
        addwf   FSR, F
        movf    INDF, W
        xorwf   ACC3, W
        movwf   SGN_T                   ; bit 7: the signs differ (only then can it overflow)
        movf    ACC3, W
        movwf   TMP2                    ; the minuend's sign
        movlw   3
        subwf   FSR, F
        movf    INDF, W
        subwf   ACC0, F
        incf    FSR, F
        movf    INDF, W
        btfss   STATUS, C
        incfsz  INDF, W                 ; subtrahend byte + borrow (0x100: ACC byte as is, borrow on)
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
        movlw   3
        subwf   FSR, F
        btfss   SGN_T, 7
        return
        movf    ACC3, W                 ; overflow when the result's sign is not the minuend's
        xorwf   TMP2, W
        andlw   0x80
        btfsc   STATUS, Z
        return
        bsf     FLAGS, FLAG_SAT
        movlw   0xFF
        movwf   ACC0
        movwf   ACC1
        movwf   ACC2
        movlw   0x7F
        movwf   ACC3
        btfss   TMP2, 7
        return
        clrf    ACC0                    ; a negative minuend: -2^31
        clrf    ACC1
        clrf    ACC2
        movlw   0x80
        movwf   ACC3
        return

; fsr_add_acc: the int32 at FSR += ACC, saturated to 32 bits (FLAG_SAT when clipped); FSR unchanged
fsr_add_acc:
        movlw   3
        addwf   FSR, F
        movf    INDF, W
        xorwf   ACC3, W
        movwf   SGN_T                   ; bit 7: the signs differ (no overflow possible)
        movlw   3
        subwf   FSR, F
        movf    ACC0, W
        addwf   INDF, F
        incf    FSR, F
        movf    ACC1, W
        btfsc   STATUS, C
        incfsz  ACC1, W
        addwf   INDF, F
        incf    FSR, F
        movf    ACC2, W
        btfsc   STATUS, C
        incfsz  ACC2, W
        addwf   INDF, F
        incf    FSR, F
        movf    ACC3, W
        btfsc   STATUS, C
        incfsz  ACC3, W
        addwf   INDF, F
        btfsc   SGN_T, 7
        goto    fa_back
        movf    INDF, W                 ; same signs: overflow when the sum's sign differs
        xorwf   ACC3, W
        andlw   0x80
        btfsc   STATUS, Z
        goto    fa_back
        bsf     FLAGS, FLAG_SAT
        movlw   0x7F                    ; 2^31 - 1 ...
        btfsc   ACC3, 7
        movlw   0x80                    ; ... or -2^31
        movwf   INDF
        movlw   0xFF
        btfsc   ACC3, 7
        movlw   0x00
        decf    FSR, F
        movwf   INDF
        decf    FSR, F
        movwf   INDF
        decf    FSR, F
        movwf   INDF
        return
fa_back:
        movlw   3
        subwf   FSR, F
        return

; =====================================================================================================
; Stage 3, vertical acceleration (kernel.py step 3): g = G2 in Q2.13 (rounded, saturated), |g|^2 exact in
; Q5.26 (the sum saturating), |g| = isqrt32n (nearest); a_v = (f.g - |g|^2) / |g| rounded to nearest
; (divr32s) and saturated to 16 bits, or 0 when |g| <= G_MIN.
G_TO_ACC        macro   g2, lo, hi
        movlw   g2
        movwf   FSR
        call    acc_load_fsr
        movlw   .16
        movwf   ARG0
        call    shr32r
        call    sat16
        movf    ACC0, W
        movwf   lo
        movf    ACC1, W
        movwf   hi
        endm

; SUM = a1 b1 + a2 b2 + a3 b3 (each product exact, the sum saturating)
DOT3            macro   a1l, a1h, b1l, b1h, a2l, a2h, b2l, b2h, a3l, a3h, b3l, b3h
        movf    a1l, W
        movwf   ACC0
        movf    a1h, W
        movwf   ACC1
        movf    b1l, W
        movwf   ARG0
        movf    b1h, W
        movwf   ARG1
        call    mul16s
        call    sum_set_acc
        movf    a2l, W
        movwf   ACC0
        movf    a2h, W
        movwf   ACC1
        movf    b2l, W
        movwf   ARG0
        movf    b2h, W
        movwf   ARG1
        call    mul16s
        call    sum_add_acc
        movf    a3l, W
        movwf   ACC0
        movf    a3h, W
        movwf   ACC1
        movf    b3l, W
        movwf   ARG0
        movf    b3h, W
        movwf   ARG1
        call    mul16s
        call    sum_add_acc
        endm

stage_av:
        G_TO_ACC G2X, GX_L, GX_H
        G_TO_ACC G2Y, GY_L, GY_H
        G_TO_ACC G2Z, GZ_L, GZ_H
        DOT3    GX_L, GX_H, GX_L, GX_H, GY_L, GY_H, GY_L, GY_H, GZ_L, GZ_H, GZ_L, GZ_H
        movf    SUM0, W                 ; N2 = |g|^2, and the root's argument
        movwf   N2_0
        movwf   ACC0
        movf    SUM1, W
        movwf   N2_1
        movwf   ACC1
        movf    SUM2, W
        movwf   N2_2
        movwf   ACC2
        movf    SUM3, W
        movwf   N2_3
        movwf   ACC3
        call    isqrt32n
        movf    ACC0, W
        movwf   GN_L
        movf    ACC1, W
        movwf   GN_H
        movlw   LOW (G_MIN + 1)         ; |g| > G_MIN <=> |g| - (G_MIN + 1) does not borrow
        subwf   ACC0, W
        movlw   HIGH (G_MIN + 1)
        btfss   STATUS, C
        addlw   1
        subwf   ACC1, W
        btfss   STATUS, C
        goto    av_zero
        DOT3    FX_L, FX_H, GX_L, GX_H, FY_L, FY_H, GY_L, GY_H, FZ_L, FZ_H, GZ_L, GZ_H
        movf    SUM0, W                 ; ACC = f.g - |g|^2 (saturating)
        movwf   ACC0
        movf    SUM1, W
        movwf   ACC1
        movf    SUM2, W
        movwf   ACC2
        movf    SUM3, W
        movwf   ACC3
        movlw   N2_0
        movwf   FSR
        call    acc_sub_fsr
        movf    GN_L, W
        movwf   ARG0
        movf    GN_H, W
        movwf   ARG1
        call    divr32s
        call    sat16
        movf    ACC0, W
        movwf   AV_L
        movf    ACC1, W
        movwf   AV_H
        return
av_zero:
        clrf    AV_L
        clrf    AV_H
        return

; sum_set_acc: SUM = ACC
sum_set_acc:
        movf    ACC0, W
        movwf   SUM0
        movf    ACC1, W
        movwf   SUM1
        movf    ACC2, W
        movwf   SUM2
        movf    ACC3, W
        movwf   SUM3
        return


steps_begin:
        #include "steps.asm"
steps_end:

kernels_begin:
        #include "mul.asm"
        #include "div.asm"
        #include "shift.asm"
        #include "sat.asm"
        #include "sqrt.asm"
kernels_end:
code_end:
    if code_end > 0x800
        error "page 0 overflows: move routines that call nothing to steps_page1.asm"
    endif
        org     0x800
page1_begin:
        #include "steps_page1.asm"
page1_end:

; Page 2: the step record (kernel.py step 6, step_record.asm) with its own copy of the kernels
; (page2_names.inc renames the copy's labels). Entered from page 1's fin_join by a jump with PCLATH = 0x10.
        org     0x1000
page2_begin:
        #include "page2_names.inc"
#define FINALISE_FAR
step_code_begin:
        #include "step_record.asm"
step_code_end:
        #include "mul.asm"
        #include "div.asm"
        #include "shift.asm"
        #include "sat.asm"
        #include "sqrt.asm"
        #include "page2_names_end.inc"
page2_end:
    if page2_end > 0x1800
        error "page 2 overflows"
    endif

; Page 1, after steps 4-5's routines: the joins to the step record (fin_join, scr_write; step_join.asm).
; They follow page 2 in the source because they use step_record.asm's I2C macros.
        org     page1_end
join_begin:
        #include "step_join.asm"
join_end:
    if join_end > 0x1000
        error "page 1 overflows"
    endif
    if (scr_write_w >> .11) != 1
        error "step_flush reaches scr_write_w with PCLATH bit 3 only: it must be in page 1"
    endif

#ifdef TEST_BUILD
        org     0x2100                  ; the data EEPROM: the configuration the host would have written
        #include "config.inc"
#endif
        end
