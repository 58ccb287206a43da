// ct_fir: causal FIR along the frame axis, per pixel, zero initial state
// (chiptwin.dsp.filters.fir_fixed, FirConfig: 8 taps, Q1.15 coefficients, 40-bit accumulator,
// RND + SAT at the output).
//
//   acc(t, p) = sum_k COEF[k] * x(t - k, p), k = 0 .. TAPS-1 added newest sample first, each
//   partial sum through AOMODE into the ACC_W-bit register; samples before the first frame
//   (t - k < 0) add nothing.
// Input: frames in raster order, NPIX beats per frame; one output beat per input beat.
// Registers: input (IN_*) . coef (COEF_W bits, COEF_S; the generator fills the ROM with
// FirConfig.coef_codes, tap k at COEFS[k*COEF_W +: COEF_W]) . product (full precision) .
// acc (ACC_W, ACC_S, frac IN_F + COEF_F) . output (OUT_*, RMODE, OMODE). History: TAPS-1 previous samples per pixel in a RAM; a frame counter (saturating
// at TAPS-1) masks the taps that reach before the first frame, so the RAM needs no clearing.
// Timing: products and the TAPS-long saturating adder chain in the accept cycle; the output
// register holds acc and the rounding logic follows it; latency 1 cycle, one beat per cycle.
// Counters: acc events (one per tap addition that saturated / wrapped) at acceptance, output
// events at the output handshake.
//
// `CT_MUTANT_ACC (harness self-test only): the accumulator is one bit narrower than ACC_W.
`default_nettype none

module ct_fir #(
    parameter integer IN_W = 16, parameter integer IN_F = 2, parameter integer IN_S = 1,
    parameter integer TAPS = 8,
    parameter integer COEF_W = 16, parameter integer COEF_F = 15, parameter integer COEF_S = 1,
    parameter [TAPS*COEF_W-1:0] COEFS = {TAPS * COEF_W{1'b0}},
    parameter integer ACC_W = 40, parameter integer ACC_S = 1,
    parameter integer AOMODE = 0,
    parameter integer NPIX = 128,
    parameter integer OUT_W = 16, parameter integer OUT_F = 2, parameter integer OUT_S = 1,
    parameter integer RMODE = 2,
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
    output wire [ACC_W-1:0] out_acc,
    output wire [OUT_W-1:0] out_y,
    output wire             out_sat,
    output wire             out_wrap,
    output wire [CNT_W-1:0] cnt_acc_sat,
    output wire [CNT_W-1:0] cnt_acc_wrap,
    output wire [CNT_W-1:0] cnt_out_sat,
    output wire [CNT_W-1:0] cnt_out_wrap
);
`ifdef CT_MUTANT_ACC
    localparam integer AW = ACC_W - 1;
`else
    localparam integer AW = ACC_W;
`endif
    localparam integer XV = IN_W + (IN_S != 0 ? 0 : 1);      // a sample as signed
    localparam integer CV = COEF_W + (COEF_S != 0 ? 0 : 1);  // a coefficient as signed
    localparam integer MW = XV + CV;                         // a product, full precision
    localparam integer PW = (NPIX > 1) ? $clog2(NPIX) : 1;
    localparam integer TW = (TAPS > 1) ? $clog2(TAPS) : 1;
    localparam [31:0] LAST_PIX32 = NPIX - 1;
    localparam [31:0] LAST_T32 = (TAPS > 1) ? TAPS - 1 : 0;
    localparam [PW-1:0] LAST_PIX = LAST_PIX32[PW-1:0];
    localparam [TW-1:0] LAST_T = LAST_T32[TW-1:0];

    reg [PW-1:0] pix;
    reg [TW-1:0] t;                    // frames seen, saturating at TAPS-1
    reg [AW-1:0] acc_q;
    wire in_fire;

    wire [TAPS*IN_W-1:0] window;       // tap k at window[k*IN_W +: IN_W]: x(t - k)
    wire [TAPS-1:0] add_sat, add_wrap;
    generate
        if (TAPS > 1) begin : g_hist
            localparam integer HW = (TAPS - 1) * IN_W;
            reg [HW-1:0] hist_mem [0:NPIX-1];  // x(t-1) in the low slot
            wire [HW-1:0] hist = hist_mem[pix];
            assign window = {hist, in_x};
            always @(posedge clk) begin
                if (in_fire) hist_mem[pix] <= window[HW-1:0];
            end
        end else begin : g_nohist
            assign window = in_x;
        end
        genvar k;
        for (k = 0; k < TAPS; k = k + 1) begin : g_tap
            localparam [31:0] K32 = k;
            wire live = (k == 0) ? 1'b1 : (t >= K32[TW-1:0]);   // x(t - k) exists
            wire [MW-1:0] xe, ce;
            ct_ext #(.IW(IN_W), .OW(MW), .SIGNED(IN_S)) u_x (
                .x(window[k*IN_W +: IN_W]), .y(xe)
            );
            ct_ext #(.IW(COEF_W), .OW(MW), .SIGNED(COEF_S)) u_c (
                .x(COEFS[k*COEF_W +: COEF_W]), .y(ce)
            );
            wire [MW-1:0] product = xe * ce;
            wire [AW-1:0] acc_in, acc_out, sum;
            if (k == 0) begin : g_first
                assign acc_in = {AW{1'b0}};
            end else begin : g_next
                assign acc_in = g_tap[k-1].acc_out;
            end
            wire s, w;
            ct_addfit #(.AW(AW), .AS(ACC_S), .TW(MW), .TS(1), .OMODE(AOMODE)) u_add (
                .acc(acc_in), .term(product), .y(sum), .sat(s), .wrap(w)
            );
            assign acc_out = live ? sum : acc_in;
            assign add_sat[k] = live & s;
            assign add_wrap[k] = live & w;
        end
    endgenerate
    wire [AW-1:0] acc_new = g_tap[TAPS-1].acc_out;

    assign in_ready = ~out_valid | out_ready;
    assign in_fire = in_valid & in_ready;
    wire out_fire = out_valid & out_ready;

    wire [AW:0] acc_s;
    ct_ext #(.IW(AW), .OW(AW + 1), .SIGNED(ACC_S)) u_accs (.x(acc_q), .y(acc_s));
    ct_ext #(.IW(AW), .OW(ACC_W), .SIGNED(ACC_S)) u_acco (.x(acc_q), .y(out_acc));
    ct_requant #(
        .IW(AW + 1), .SH(IN_F + COEF_F - OUT_F), .RMODE(RMODE), .OW(OUT_W), .OSIGNED(OUT_S), .OMODE(OMODE)
    ) u_out (.x(acc_s), .y(out_y), .sat(out_sat), .wrap(out_wrap));

    ct_events #(.W(1), .CNT_W(CNT_W)) u_ev_out (
        .clk(clk), .rst(rst), .en(out_fire), .sat(out_sat), .wrap(out_wrap),
        .cnt_sat(cnt_out_sat), .cnt_wrap(cnt_out_wrap)
    );
    ct_events #(.W(TAPS), .CNT_W(CNT_W)) u_ev_acc (
        .clk(clk), .rst(rst), .en(in_fire), .sat(add_sat), .wrap(add_wrap),
        .cnt_sat(cnt_acc_sat), .cnt_wrap(cnt_acc_wrap)
    );

    always @(posedge clk) begin
        if (rst) begin
            pix <= {PW{1'b0}};
            t <= {TW{1'b0}};
            out_valid <= 1'b0;
        end else begin
            if (in_ready) out_valid <= in_valid;
            if (in_fire) begin
                if (pix == LAST_PIX) begin
                    pix <= {PW{1'b0}};
                    if (t != LAST_T) t <= t + {{(TW - 1){1'b0}}, 1'b1};
                end else begin
                    pix <= pix + {{(PW - 1){1'b0}}, 1'b1};
                end
            end
        end
    end

    always @(posedge clk) begin
        if (in_fire) acc_q <= acc_new;
    end
endmodule

`default_nettype wire
