// ct_kinetics: kinetics-weighted accumulation (matched filter of an exponential light curve)
// (chiptwin.dsp.filters.kinetics_weighted_fixed, KineticsConfig):
//
//   out(p) = requant(NORM * sum_j W[j] * y(j, p)),  j = 0 .. N-1 added in order.
//
// Input: frames in raster order, NPIX beats per frame, runs of N frames (one decay).
// Registers: input (IN_*) . weights (COEF_W bits, COEF_S; ROM filled by the generator with
// KineticsConfig.weight_codes, weight j at WEIGHTS[j*COEF_W +: COEF_W]) . product (full
// precision) . acc (ACC_W, ACC_S, frac IN_F + COEF_F, per pixel, each partial sum through
// AOMODE) . norm (unsigned NORM_W-bit constant NORM, NORM_F fractional bits) . scaled
// (acc * norm, full precision) . output (OUT_*, RMODE then OMODE).
// One output beat per pixel of the last frame of a run: out_acc and out_y.
// Timing: multiply-accumulate in the accept cycle; the output register holds acc, the scale
// and rounding logic follows it; latency 1 cycle, one beat per cycle; beats that end no run
// are accepted while the output is stalled.
//
// `CT_MUTANT_ACC (harness self-test only): the accumulator is one bit narrower than ACC_W.
`default_nettype none

module ct_kinetics #(
    parameter integer IN_W = 16, parameter integer IN_F = 2, parameter integer IN_S = 1,
    parameter integer N = 16,
    parameter integer COEF_W = 16, parameter integer COEF_F = 15, parameter integer COEF_S = 0,
    parameter [N*COEF_W-1:0] WEIGHTS = {N * COEF_W{1'b0}},
    parameter integer ACC_W = 36, parameter integer ACC_S = 1,
    parameter integer AOMODE = 0,
    parameter integer NORM_W = 18, parameter integer NORM_F = 17,
    parameter [63:0]  NORM = 64'd0,
    parameter integer NPIX = 128,
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
    localparam integer XV = IN_W + (IN_S != 0 ? 0 : 1);
    localparam integer CV = COEF_W + (COEF_S != 0 ? 0 : 1);
    localparam integer MW = XV + CV;                      // a product, full precision
    localparam integer AV = AW + (ACC_S != 0 ? 0 : 1);
    localparam integer SW = AV + NORM_W + 1;              // scaled register
    localparam integer PW = (NPIX > 1) ? $clog2(NPIX) : 1;
    localparam integer JW = (N > 1) ? $clog2(N) : 1;
    localparam [31:0] LAST_PIX32 = NPIX - 1;
    localparam [31:0] LAST_J32 = N - 1;
    localparam [PW-1:0] LAST_PIX = LAST_PIX32[PW-1:0];
    localparam [JW-1:0] LAST_J = LAST_J32[JW-1:0];
    localparam [NORM_W:0] NORM_CODE = {1'b0, NORM[NORM_W-1:0]};

    reg [PW-1:0] pix;
    reg [JW-1:0] j;
    reg [AW-1:0] acc_mem [0:NPIX-1];
    reg [AW-1:0] acc_q;

    wire first = (j == {JW{1'b0}});
    wire emit = (j == LAST_J);
    // weight ROM: a constant table indexed by the frame of the run
    reg [COEF_W-1:0] weight;
    integer wi;
    always @* begin
        weight = WEIGHTS[COEF_W-1:0];
        for (wi = 1; wi < N; wi = wi + 1) begin
            if ({{(32 - JW){1'b0}}, j} == wi) weight = WEIGHTS[wi*COEF_W +: COEF_W];
        end
    end
    wire [MW-1:0] xe, we;
    ct_ext #(.IW(IN_W), .OW(MW), .SIGNED(IN_S)) u_x (.x(in_x), .y(xe));
    ct_ext #(.IW(COEF_W), .OW(MW), .SIGNED(COEF_S)) u_w (.x(weight), .y(we));
    wire [MW-1:0] product = xe * we;

    wire [AW-1:0] acc_old = first ? {AW{1'b0}} : acc_mem[pix];
    wire [AW-1:0] acc_new;
    wire acc_sat, acc_wrap;
    ct_addfit #(.AW(AW), .AS(ACC_S), .TW(MW), .TS(1), .OMODE(AOMODE)) u_acc (
        .acc(acc_old), .term(product), .y(acc_new), .sat(acc_sat), .wrap(acc_wrap)
    );

    assign in_ready = ~emit | ~out_valid | out_ready;
    wire in_fire = in_valid & in_ready;
    wire out_fire = out_valid & out_ready;

    wire [SW-1:0] acc_s, norm_s;
    ct_ext #(.IW(AW), .OW(SW), .SIGNED(ACC_S)) u_accs (.x(acc_q), .y(acc_s));
    ct_ext #(.IW(NORM_W + 1), .OW(SW), .SIGNED(1)) u_norm (.x(NORM_CODE), .y(norm_s));
    ct_ext #(.IW(AW), .OW(ACC_W), .SIGNED(ACC_S)) u_acco (.x(acc_q), .y(out_acc));
    wire [SW-1:0] scaled = acc_s * norm_s;   // exact
    ct_requant #(
        .IW(SW), .SH(IN_F + COEF_F + NORM_F - OUT_F), .RMODE(RMODE),
        .OW(OUT_W), .OSIGNED(OUT_S), .OMODE(OMODE)
    ) u_out (.x(scaled), .y(out_y), .sat(out_sat), .wrap(out_wrap));

    ct_events #(.W(1), .CNT_W(CNT_W)) u_ev_out (
        .clk(clk), .rst(rst), .en(out_fire), .sat(out_sat), .wrap(out_wrap),
        .cnt_sat(cnt_out_sat), .cnt_wrap(cnt_out_wrap)
    );
    ct_events #(.W(1), .CNT_W(CNT_W)) u_ev_acc (
        .clk(clk), .rst(rst), .en(in_fire), .sat(acc_sat), .wrap(acc_wrap),
        .cnt_sat(cnt_acc_sat), .cnt_wrap(cnt_acc_wrap)
    );

    always @(posedge clk) begin
        if (rst) begin
            pix <= {PW{1'b0}};
            j <= {JW{1'b0}};
            out_valid <= 1'b0;
        end else begin
            if (out_fire) out_valid <= 1'b0;
            if (in_fire) begin
                if (emit) out_valid <= 1'b1;
                if (pix == LAST_PIX) begin
                    pix <= {PW{1'b0}};
                    j <= emit ? {JW{1'b0}} : j + {{(JW - 1){1'b0}}, 1'b1};
                end else begin
                    pix <= pix + {{(PW - 1){1'b0}}, 1'b1};
                end
            end
        end
    end

    always @(posedge clk) begin
        if (in_fire) begin
            acc_mem[pix] <= acc_new;
            if (emit) acc_q <= acc_new;
        end
    end
endmodule

`default_nettype wire
