// ct_cms: correlated multiple sampling, out = (sum of M signal samples - sum of M reset samples)/M
// (chiptwin.dsp.frame_ops.cms_fixed, CmsConfig).
//
// Input: per frame 2M rows of NPIX beats in raster order: the M reset samples of every pixel,
// then the M signal samples (the layout of chiptwin.dsp.pipeline.Frame.codes).
// Registers: input (IN_*) . sum_reset, sum_signal (ACC_W bits, ACC_S, per pixel, samples added
// in order, each partial sum through AOMODE) . diff (sum_signal - sum_reset, full precision,
// signed) . divide step (ct_divide) . output (OUT_*, RMODE then OMODE).
// One output beat per pixel of the last signal row: out_diff and out_y.
// Timing: one accumulator update per accepted beat (a single adder, shared by both sums);
// the output register holds diff and the divide/round logic follows it, latency 1 cycle,
// one beat per cycle; beats that end no frame are accepted while the output is stalled.
//
// `CT_MUTANT_ACC (harness self-test only): the accumulators are one bit narrower than ACC_W.
`default_nettype none

module ct_cms #(
    parameter integer IN_W = 13, parameter integer IN_F = 0, parameter integer IN_S = 0,
    parameter integer ACC_W = 15, parameter integer ACC_S = 0,
    parameter integer AOMODE = 0,
    parameter integer M = 4,
    parameter integer NPIX = 128,
    parameter integer RECIP_W = 18, parameter integer RECIP_F = 19,
    parameter [63:0]  RECIP = 64'd0,
    parameter integer OUT_W = 16, parameter integer OUT_F = 2, parameter integer OUT_S = 1,
    parameter integer RMODE = 5,
    parameter integer OMODE = 1,
    parameter integer CNT_W = 48
) (
    input  wire             clk,
    input  wire             rst,
    input  wire             in_valid,
    output wire             in_ready,
    input  wire [IN_W-1:0]  in_x,
    output reg              out_valid,
    input  wire             out_ready,
    output wire [ACC_W+1:0] out_diff,
    output wire [OUT_W-1:0] out_y,
    output wire             out_sat,
    output wire             out_wrap,
    output wire [CNT_W-1:0] cnt_reset_sat,
    output wire [CNT_W-1:0] cnt_reset_wrap,
    output wire [CNT_W-1:0] cnt_signal_sat,
    output wire [CNT_W-1:0] cnt_signal_wrap,
    output wire [CNT_W-1:0] cnt_out_sat,
    output wire [CNT_W-1:0] cnt_out_wrap
);
`ifdef CT_MUTANT_ACC
    localparam integer AW = ACC_W - 1;
`else
    localparam integer AW = ACC_W;
`endif
    localparam integer AV = AW + (ACC_S != 0 ? 0 : 1);   // a sum as a signed value
    localparam integer DW = AV + 1;                      // diff register
    localparam integer PW = (NPIX > 1) ? $clog2(NPIX) : 1;
    localparam integer RW = $clog2(2 * M);
    localparam [31:0] LAST_PIX32 = NPIX - 1;
    localparam [31:0] LAST_R32 = 2 * M - 1;
    localparam [31:0] FIRST_SIG32 = M;
    localparam [PW-1:0] LAST_PIX = LAST_PIX32[PW-1:0];
    localparam [RW-1:0] LAST_R = LAST_R32[RW-1:0];
    localparam [RW-1:0] FIRST_SIG = FIRST_SIG32[RW-1:0];

    reg [PW-1:0] pix;
    reg [RW-1:0] r;
    reg [AW-1:0] reset_mem [0:NPIX-1];
    reg [AW-1:0] signal_mem [0:NPIX-1];
    reg [DW-1:0] diff_q;

    wire is_reset = (r < FIRST_SIG);
    wire first = (r == {RW{1'b0}}) | (r == FIRST_SIG);
    wire emit = (r == LAST_R);
    wire [AW-1:0] sum_reset = reset_mem[pix];
    wire [AW-1:0] acc_old = first ? {AW{1'b0}} : (is_reset ? sum_reset : signal_mem[pix]);
    wire [AW-1:0] acc_new;
    wire acc_sat, acc_wrap;
    ct_addfit #(.AW(AW), .AS(ACC_S), .TW(IN_W), .TS(IN_S), .OMODE(AOMODE)) u_acc (
        .acc(acc_old), .term(in_x), .y(acc_new), .sat(acc_sat), .wrap(acc_wrap)
    );
    wire [DW-1:0] sig_w, rst_w;
    ct_ext #(.IW(AW), .OW(DW), .SIGNED(ACC_S)) u_sig (.x(acc_new), .y(sig_w));
    ct_ext #(.IW(AW), .OW(DW), .SIGNED(ACC_S)) u_rst (.x(sum_reset), .y(rst_w));
    wire [DW-1:0] diff = sig_w - rst_w;   // used on the last signal row only

    assign in_ready = ~emit | ~out_valid | out_ready;
    wire in_fire = in_valid & in_ready;
    wire out_fire = out_valid & out_ready;

    ct_ext #(.IW(DW), .OW(ACC_W + 2), .SIGNED(1)) u_diffo (.x(diff_q), .y(out_diff));
    ct_divide #(
        .IW(DW), .IN_F(IN_F), .N(M), .RECIP_W(RECIP_W), .RECIP_F(RECIP_F), .RECIP(RECIP),
        .OUT_W(OUT_W), .OUT_F(OUT_F), .OUT_S(OUT_S), .RMODE(RMODE), .OMODE(OMODE)
    ) u_div (.x(diff_q), .y(out_y), .sat(out_sat), .wrap(out_wrap));

    ct_events #(.W(1), .CNT_W(CNT_W)) u_ev_out (
        .clk(clk), .rst(rst), .en(out_fire), .sat(out_sat), .wrap(out_wrap),
        .cnt_sat(cnt_out_sat), .cnt_wrap(cnt_out_wrap)
    );
    ct_events #(.W(1), .CNT_W(CNT_W)) u_ev_reset (
        .clk(clk), .rst(rst), .en(in_fire & is_reset), .sat(acc_sat), .wrap(acc_wrap),
        .cnt_sat(cnt_reset_sat), .cnt_wrap(cnt_reset_wrap)
    );
    ct_events #(.W(1), .CNT_W(CNT_W)) u_ev_signal (
        .clk(clk), .rst(rst), .en(in_fire & ~is_reset), .sat(acc_sat), .wrap(acc_wrap),
        .cnt_sat(cnt_signal_sat), .cnt_wrap(cnt_signal_wrap)
    );

    always @(posedge clk) begin
        if (rst) begin
            pix <= {PW{1'b0}};
            r <= {RW{1'b0}};
            out_valid <= 1'b0;
        end else begin
            if (out_fire) out_valid <= 1'b0;
            if (in_fire) begin
                if (emit) out_valid <= 1'b1;
                if (pix == LAST_PIX) begin
                    pix <= {PW{1'b0}};
                    r <= emit ? {RW{1'b0}} : r + {{(RW - 1){1'b0}}, 1'b1};
                end else begin
                    pix <= pix + {{(PW - 1){1'b0}}, 1'b1};
                end
            end
        end
    end

    always @(posedge clk) begin
        if (in_fire) begin
            if (is_reset) reset_mem[pix] <= acc_new;
            else signal_mem[pix] <= acc_new;
            if (emit) diff_q <= diff;
        end
    end
endmodule

`default_nettype wire
