// ct_average: N-frame accumulation into a per-pixel accumulator, then division by N
// (chiptwin.dsp.frame_ops.accumulate_frames_fixed / average_frames_fixed, AverageConfig).
//
// Input: frames in raster order, NPIX beats per frame; runs of N consecutive frames.
// Registers: input (IN_*) . acc (ACC_W bits, ACC_S, IN_F fractional bits, one per pixel, reset
// to 0 at the first frame of each run, each partial sum through AOMODE) . divide step
// (ct_divide: shift, or RECIP product) . output (OUT_*, RMODE then OMODE).
// One output beat per pixel of the last frame of a run: out_acc (the sum) and out_y (the mean).
// Timing: accumulator RAM read-modify-write in the accept cycle; the output register holds the
// sum and the divide/round/saturate logic follows it, latency 1 cycle, one beat per cycle.
// Beats that end no run are accepted even while the output is stalled.
// Counters: acc events at acceptance (one per update that saturated / wrapped), output events
// at the output handshake.
//
// `CT_MUTANT_ACC (harness self-test only): the accumulator is one bit narrower than ACC_W.
`default_nettype none

module ct_average #(
    parameter integer IN_W = 16, parameter integer IN_F = 2, parameter integer IN_S = 1,
    parameter integer ACC_W = 18, parameter integer ACC_S = 1,
    parameter integer AOMODE = 0,
    parameter integer N = 4,
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
    localparam integer PW = (NPIX > 1) ? $clog2(NPIX) : 1;
    localparam integer JW = (N > 1) ? $clog2(N) : 1;
    localparam [31:0] LAST_PIX32 = NPIX - 1;
    localparam [31:0] LAST_J32 = N - 1;
    localparam [PW-1:0] LAST_PIX = LAST_PIX32[PW-1:0];
    localparam [JW-1:0] LAST_J = LAST_J32[JW-1:0];

    reg [PW-1:0] pix;
    reg [JW-1:0] j;
    reg [AW-1:0] acc_mem [0:NPIX-1];
    reg [AW-1:0] acc_q;

    wire first = (j == {JW{1'b0}});
    wire emit = (j == LAST_J);
    wire [AW-1:0] acc_old = first ? {AW{1'b0}} : acc_mem[pix];
    wire [AW-1:0] acc_new;
    wire acc_sat, acc_wrap;
    ct_addfit #(.AW(AW), .AS(ACC_S), .TW(IN_W), .TS(IN_S), .OMODE(AOMODE)) u_acc (
        .acc(acc_old), .term(in_x), .y(acc_new), .sat(acc_sat), .wrap(acc_wrap)
    );

    assign in_ready = ~emit | ~out_valid | out_ready;
    wire in_fire = in_valid & in_ready;
    wire out_fire = out_valid & out_ready;

    wire [AW:0] acc_s;   // the sum as a signed value, for the divide step
    ct_ext #(.IW(AW), .OW(AW + 1), .SIGNED(ACC_S)) u_accs (.x(acc_q), .y(acc_s));
    ct_ext #(.IW(AW), .OW(ACC_W), .SIGNED(ACC_S)) u_acco (.x(acc_q), .y(out_acc));
    ct_divide #(
        .IW(AW + 1), .IN_F(IN_F), .N(N), .RECIP_W(RECIP_W), .RECIP_F(RECIP_F), .RECIP(RECIP),
        .OUT_W(OUT_W), .OUT_F(OUT_F), .OUT_S(OUT_S), .RMODE(RMODE), .OMODE(OMODE)
    ) u_div (.x(acc_s), .y(out_y), .sat(out_sat), .wrap(out_wrap));

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
