// ct_chain: the chip's DSP chain (chiptwin.dsp.chain.ChainConfig; the steps of
// chiptwin.dsp.pipeline): CMS of every frame -> the first K CMS frames average into the dark
// reference (a per-pixel RAM) -> every later CMS frame minus the dark reference -> N-frame
// averaging.
//
// Input: ADC samples, per frame 2M rows of NPIX beats (M reset rows, then M signal rows); the
// first K frames are dark frames. Output: a tagged stream, out_tag 0 = one dark-reference word
// per pixel (once, after frame K-1), out_tag 1 = one average per pixel per run of N frames.
// Blocks: ct_cms -> ct_average (N = K, the dark reference) | ct_background -> ct_average (N).
// The dark path has priority on the output; the word of the other tag reads 0. A background beat waits while a dark-reference
// word is still on its way into the RAM (so even NPIX = 1 reads the finished reference).
// Counters: see the cnt_* ports, one pair (sat, wrap) per register of the four configs.
`default_nettype none

module ct_chain #(
    parameter integer NPIX = 128,
    // CMS (CmsConfig)
    parameter integer CMS_IN_W = 13, parameter integer CMS_IN_F = 0, parameter integer CMS_IN_S = 0,
    parameter integer M = 4,
    parameter integer CMS_ACC_W = 15, parameter integer CMS_ACC_S = 0,
    parameter integer CMS_AOMODE = 0,
    parameter integer CMS_RECIP_W = 18, parameter integer CMS_RECIP_F = 19,
    parameter [63:0]  CMS_RECIP = 64'd0,
    parameter integer CMS_OUT_W = 16, parameter integer CMS_OUT_F = 2, parameter integer CMS_OUT_S = 1,
    parameter integer CMS_RMODE = 5, parameter integer CMS_OMODE = 1,
    // dark reference (AverageConfig n = K, input = CMS output)
    parameter integer K = 16,
    parameter integer DARK_ACC_W = 20, parameter integer DARK_ACC_S = 1,
    parameter integer DARK_AOMODE = 0,
    parameter integer DARK_RECIP_W = 18, parameter integer DARK_RECIP_F = 19,
    parameter [63:0]  DARK_RECIP = 64'd0,
    parameter integer DARK_OUT_W = 20, parameter integer DARK_OUT_F = 6, parameter integer DARK_OUT_S = 1,
    parameter integer DARK_RMODE = 5, parameter integer DARK_OMODE = 1,
    // background subtraction (BackgroundConfig: CMS output - dark reference)
    parameter integer BG_OUT_W = 21, parameter integer BG_OUT_F = 6, parameter integer BG_OUT_S = 1,
    parameter integer BG_RMODE = 5, parameter integer BG_OMODE = 1,
    // N-frame average (AverageConfig, input = background output)
    parameter integer N = 4,
    parameter integer AVG_ACC_W = 23, parameter integer AVG_ACC_S = 1,
    parameter integer AVG_AOMODE = 0,
    parameter integer AVG_RECIP_W = 18, parameter integer AVG_RECIP_F = 19,
    parameter [63:0]  AVG_RECIP = 64'd0,
    parameter integer AVG_OUT_W = 23, parameter integer AVG_OUT_F = 8, parameter integer AVG_OUT_S = 1,
    parameter integer AVG_RMODE = 5, parameter integer AVG_OMODE = 1,
    parameter integer CNT_W = 48
) (
    input  wire                  clk,
    input  wire                  rst,
    input  wire                  in_valid,
    output wire                  in_ready,
    input  wire [CMS_IN_W-1:0]   in_x,
    output wire                  out_valid,
    input  wire                  out_ready,
    output wire                  out_tag,
    output wire [DARK_OUT_W-1:0] out_dark,
    output wire [AVG_OUT_W-1:0]  out_avg,
    output wire [CNT_W-1:0]      cnt_cms_reset_sat,
    output wire [CNT_W-1:0]      cnt_cms_reset_wrap,
    output wire [CNT_W-1:0]      cnt_cms_signal_sat,
    output wire [CNT_W-1:0]      cnt_cms_signal_wrap,
    output wire [CNT_W-1:0]      cnt_cms_out_sat,
    output wire [CNT_W-1:0]      cnt_cms_out_wrap,
    output wire [CNT_W-1:0]      cnt_dark_acc_sat,
    output wire [CNT_W-1:0]      cnt_dark_acc_wrap,
    output wire [CNT_W-1:0]      cnt_dark_out_sat,
    output wire [CNT_W-1:0]      cnt_dark_out_wrap,
    output wire [CNT_W-1:0]      cnt_bg_out_sat,
    output wire [CNT_W-1:0]      cnt_bg_out_wrap,
    output wire [CNT_W-1:0]      cnt_avg_acc_sat,
    output wire [CNT_W-1:0]      cnt_avg_acc_wrap,
    output wire [CNT_W-1:0]      cnt_avg_out_sat,
    output wire [CNT_W-1:0]      cnt_avg_out_wrap
);
    localparam integer PW = (NPIX > 1) ? $clog2(NPIX) : 1;
    localparam integer FW = $clog2(K + 1);
    localparam [31:0] LAST_PIX32 = NPIX - 1;
    localparam [31:0] K32 = K;
    localparam [PW-1:0] LAST_PIX = LAST_PIX32[PW-1:0];
    localparam [FW-1:0] K_F = K32[FW-1:0];

    // ---- CMS ---------------------------------------------------------------------------
    wire cms_valid, cms_ready;
    wire [CMS_OUT_W-1:0] cms_y;
    /* verilator lint_off UNUSEDSIGNAL */
    wire [CMS_ACC_W+1:0] cms_diff;      // observability only
    wire cms_sat, cms_wrap;
    /* verilator lint_on UNUSEDSIGNAL */
    ct_cms #(
        .IN_W(CMS_IN_W), .IN_F(CMS_IN_F), .IN_S(CMS_IN_S),
        .ACC_W(CMS_ACC_W), .ACC_S(CMS_ACC_S), .AOMODE(CMS_AOMODE), .M(M), .NPIX(NPIX),
        .RECIP_W(CMS_RECIP_W), .RECIP_F(CMS_RECIP_F), .RECIP(CMS_RECIP),
        .OUT_W(CMS_OUT_W), .OUT_F(CMS_OUT_F), .OUT_S(CMS_OUT_S),
        .RMODE(CMS_RMODE), .OMODE(CMS_OMODE), .CNT_W(CNT_W)
    ) u_cms (
        .clk(clk), .rst(rst), .in_valid(in_valid), .in_ready(in_ready), .in_x(in_x),
        .out_valid(cms_valid), .out_ready(cms_ready), .out_diff(cms_diff), .out_y(cms_y),
        .out_sat(cms_sat), .out_wrap(cms_wrap),
        .cnt_reset_sat(cnt_cms_reset_sat), .cnt_reset_wrap(cnt_cms_reset_wrap),
        .cnt_signal_sat(cnt_cms_signal_sat), .cnt_signal_wrap(cnt_cms_signal_wrap),
        .cnt_out_sat(cnt_cms_out_sat), .cnt_out_wrap(cnt_cms_out_wrap)
    );

    // ---- demux: dark frames, then frames -------------------------------------------------
    reg [PW-1:0] pix;          // pixel of the CMS output stream
    reg [FW-1:0] frame;        // CMS frames delivered, saturating at K
    wire dark_phase = (frame != K_F);
    wire dark_in_ready, dark_valid, bg_in_ready;
    wire dark_out_ready;
    wire bg_stall = dark_valid;           // a dark-reference word is not yet in the RAM
    assign cms_ready = dark_phase ? dark_in_ready : (bg_in_ready & ~bg_stall);
    wire cms_fire = cms_valid & cms_ready;

    // ---- dark reference --------------------------------------------------------------------
    wire [DARK_OUT_W-1:0] dark_y;
    /* verilator lint_off UNUSEDSIGNAL */
    wire [DARK_ACC_W-1:0] dark_acc;
    wire dark_sat, dark_wrap;
    /* verilator lint_on UNUSEDSIGNAL */
    ct_average #(
        .IN_W(CMS_OUT_W), .IN_F(CMS_OUT_F), .IN_S(CMS_OUT_S),
        .ACC_W(DARK_ACC_W), .ACC_S(DARK_ACC_S), .AOMODE(DARK_AOMODE), .N(K), .NPIX(NPIX),
        .RECIP_W(DARK_RECIP_W), .RECIP_F(DARK_RECIP_F), .RECIP(DARK_RECIP),
        .OUT_W(DARK_OUT_W), .OUT_F(DARK_OUT_F), .OUT_S(DARK_OUT_S),
        .RMODE(DARK_RMODE), .OMODE(DARK_OMODE), .CNT_W(CNT_W)
    ) u_dark (
        .clk(clk), .rst(rst), .in_valid(cms_valid & dark_phase), .in_ready(dark_in_ready),
        .in_x(cms_y), .out_valid(dark_valid), .out_ready(dark_out_ready),
        .out_acc(dark_acc), .out_y(dark_y), .out_sat(dark_sat), .out_wrap(dark_wrap),
        .cnt_acc_sat(cnt_dark_acc_sat), .cnt_acc_wrap(cnt_dark_acc_wrap),
        .cnt_out_sat(cnt_dark_out_sat), .cnt_out_wrap(cnt_dark_out_wrap)
    );
    reg [DARK_OUT_W-1:0] dark_mem [0:NPIX-1];
    reg [PW-1:0] dark_pix;                // pixel of the dark-reference output stream
    wire dark_fire = dark_valid & dark_out_ready;

    // ---- background subtraction and averaging ----------------------------------------------
    wire bg_valid, bg_ready;
    wire [BG_OUT_W-1:0] bg_y;
    /* verilator lint_off UNUSEDSIGNAL */
    wire bg_sat, bg_wrap;
    /* verilator lint_on UNUSEDSIGNAL */
    ct_background #(
        .IN_W(CMS_OUT_W), .IN_F(CMS_OUT_F), .IN_S(CMS_OUT_S),
        .DK_W(DARK_OUT_W), .DK_F(DARK_OUT_F), .DK_S(DARK_OUT_S),
        .OUT_W(BG_OUT_W), .OUT_F(BG_OUT_F), .OUT_S(BG_OUT_S),
        .RMODE(BG_RMODE), .OMODE(BG_OMODE), .CNT_W(CNT_W)
    ) u_bg (
        .clk(clk), .rst(rst), .in_valid(cms_valid & ~dark_phase & ~bg_stall),
        .in_ready(bg_in_ready), .in_x(cms_y), .in_dark(dark_mem[pix]),
        .out_valid(bg_valid), .out_ready(bg_ready), .out_y(bg_y),
        .out_sat(bg_sat), .out_wrap(bg_wrap),
        .cnt_out_sat(cnt_bg_out_sat), .cnt_out_wrap(cnt_bg_out_wrap)
    );
    wire avg_valid, avg_out_ready;
    wire [AVG_OUT_W-1:0] avg_y;
    /* verilator lint_off UNUSEDSIGNAL */
    wire [AVG_ACC_W-1:0] avg_acc;
    wire avg_sat, avg_wrap;
    /* verilator lint_on UNUSEDSIGNAL */
    ct_average #(
        .IN_W(BG_OUT_W), .IN_F(BG_OUT_F), .IN_S(BG_OUT_S),
        .ACC_W(AVG_ACC_W), .ACC_S(AVG_ACC_S), .AOMODE(AVG_AOMODE), .N(N), .NPIX(NPIX),
        .RECIP_W(AVG_RECIP_W), .RECIP_F(AVG_RECIP_F), .RECIP(AVG_RECIP),
        .OUT_W(AVG_OUT_W), .OUT_F(AVG_OUT_F), .OUT_S(AVG_OUT_S),
        .RMODE(AVG_RMODE), .OMODE(AVG_OMODE), .CNT_W(CNT_W)
    ) u_avg (
        .clk(clk), .rst(rst), .in_valid(bg_valid), .in_ready(bg_ready), .in_x(bg_y),
        .out_valid(avg_valid), .out_ready(avg_out_ready),
        .out_acc(avg_acc), .out_y(avg_y), .out_sat(avg_sat), .out_wrap(avg_wrap),
        .cnt_acc_sat(cnt_avg_acc_sat), .cnt_acc_wrap(cnt_avg_acc_wrap),
        .cnt_out_sat(cnt_avg_out_sat), .cnt_out_wrap(cnt_avg_out_wrap)
    );

    // ---- output: the dark reference first ----------------------------------------------------
    assign out_valid = dark_valid | avg_valid;
    assign out_tag = ~dark_valid;
    // the word of the other tag is driven to zero: no undefined bits on a valid beat
    assign out_dark = dark_valid ? dark_y : {DARK_OUT_W{1'b0}};
    assign out_avg = dark_valid ? {AVG_OUT_W{1'b0}} : avg_y;
    assign dark_out_ready = out_ready;
    assign avg_out_ready = out_ready & ~dark_valid;

    always @(posedge clk) begin
        if (rst) begin
            pix <= {PW{1'b0}};
            frame <= {FW{1'b0}};
            dark_pix <= {PW{1'b0}};
        end else begin
            if (cms_fire) begin
                if (pix == LAST_PIX) begin
                    pix <= {PW{1'b0}};
                    if (dark_phase) frame <= frame + {{(FW - 1){1'b0}}, 1'b1};
                end else begin
                    pix <= pix + {{(PW - 1){1'b0}}, 1'b1};
                end
            end
            if (dark_fire) dark_pix <= (dark_pix == LAST_PIX) ? {PW{1'b0}}
                                                              : dark_pix + {{(PW - 1){1'b0}}, 1'b1};
        end
    end

    always @(posedge clk) begin
        if (dark_fire) dark_mem[dark_pix] <= dark_y;
    end
endmodule

`default_nettype wire
