!> The force kernel's work on one chunk of cells of a grid row (iem_cell_kernel gathers the
!> chunk's two node rows and sums its corner forces per node): the edges of the chunk, each
!> measured once; the law's coefficients and the damping stresses of the elastic cells (whose
!> fused loops are iem_cell_elastic's); and the general path, with the intermediates in
!> arrays, for the nonlinear springs and the cells that fracture has reached.
module iem_cell_chunk
  use iem_kinds, only: wp
  use iem_spring_constants, only: cell_constants_t, law_bending
  use iem_nonlinear_springs, only: nonlinear_springs_t
  use iem_cell_laws, only: chunk, cell_law, cell_law_mixed, nonlinear_law
  use iem_fracture, only: fracture_t
  use iem_fracture_kernel, only: fracture_chunk, damaged_cell
  implicit none
  private
  public :: edge_row_t, edge_col_t, chunk_edges, edge_measure, edge_limit, chunk_general, &
            law_coefficients, damping_stresses

  !> The largest |(l/l0)^2 - 1| of an edge that edge_near measures.
  real(wp), parameter :: near_limit = 1.0_wp/16.0_wp

  !> A node row of a chunk and its horizontal edges: the displacements u(0:m, 2) of its nodes
  !> 0..m and, for edges 1..m (from node c-1 to node c), the unit vector (x, y), inverse
  !> length li and engineering strain st. A chunk's cells lie between a bottom and a top row.
  type :: edge_row_t
    real(wp) :: u(0:chunk, 2)
    real(wp) :: x(chunk), y(chunk), li(chunk), st(chunk)
  end type edge_row_t

  !> The vertical edges 0..m of a chunk, from the bottom to the top row (cell c has edge c-1
  !> on its left and edge c on its right): unit vector, inverse length and strain.
  type :: edge_col_t
    real(wp) :: x(0:chunk), y(0:chunk), li(0:chunk), st(0:chunk)
  end type edge_col_t

contains

  !> The edges of a chunk of m cells between the node rows bot and top (their displacements
  !> given): the top row's edges, the vertical edges, and with bottom the bottom row's edges
  !> (else already there: measured as the top row of the chunk below). n_out counts the edges
  !> whose |(l/l0)^2 - 1| passes near (edge_limit): of the bottom row (when measured here),
  !> the top row and the vertical edges. Each edge depends on its two nodes only.
  pure subroutine chunk_edges(k, m, bot, top, bottom, near, v, n_out)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    type(edge_row_t), intent(inout) :: bot, top
    logical, intent(in) :: bottom
    real(wp), intent(in) :: near
    type(edge_col_t), intent(out) :: v
    integer, intent(inout) :: n_out(3)
    ! (edge_loop/iem_edge_near.inc's variables)
    real(wp) :: par, perp, l0, il0, d, h, e, a, b, li, st
    integer :: c, n, nt, past, mp
    ! the edge loops run on to a whole number of vectors (mp edges): the nodes past m repeat
    ! node m, so that the edges past m, which nothing reads, are unstretched (along a row) or
    ! edge m again (vertical), and each count stays 0 where it was (only whether a count is 0
    ! is read)
    mp = padded(m)
    do c = m + 1, mp
      top%u(c, :) = top%u(m, :)
      bot%u(c, :) = bot%u(m, :)
    end do
    if (bottom) call row_edges(k, m, near, bot%u, bot%x, bot%y, bot%li, bot%st, n_out(1))
    ! a vertical edge: along it the y displacements, across it the x ones
    par = top%u(0, 2) - bot%u(0, 2)
    perp = top%u(0, 1) - bot%u(0, 1)
    l0 = k%ly
    il0 = k%il0(2)
    include 'edge_loop/iem_edge_near.inc'
    v%y(0) = a
    v%x(0) = b
    v%li(0) = li
    v%st(0) = st
    n = past
    ! the top row's edges and the vertical ones in one loop (the top row's nodes read once)
    nt = 0
    do c = 1, mp
      par = top%u(c, 1) - top%u(c - 1, 1)
      perp = top%u(c, 2) - top%u(c - 1, 2)
      l0 = k%lx
      il0 = k%il0(1)
      include 'edge_loop/iem_edge_near.inc'
      top%x(c) = a
      top%y(c) = b
      top%li(c) = li
      top%st(c) = st
      nt = nt + past
      par = top%u(c, 2) - bot%u(c, 2)
      perp = top%u(c, 1) - bot%u(c, 1)
      l0 = k%ly
      il0 = k%il0(2)
      include 'edge_loop/iem_edge_near.inc'
      v%y(c) = a
      v%x(c) = b
      v%li(c) = li
      v%st(c) = st
      n = n + past
    end do
    n_out(2) = nt
    n_out(3) = n
    if (nt > 0) call row_far(k, m, top%u, top%x, top%y, top%li, top%st)
    if (n == 0) return
    do c = 0, m
      call edge_far(top%u(c, 2) - bot%u(c, 2), top%u(c, 1) - bot%u(c, 1), k%ly, k%il0(2), &
                    v%y(c), v%x(c), v%li(c), v%st(c))
    end do
  end subroutine chunk_edges

  !> The horizontal edges 1..m of a node row of displacements u(0:m, 2): unit vector (x, y),
  !> inverse length ri and strain rs of each; n_out of them past near (edge_limit). Runs on to
  !> padded(m) edges: u past m is to repeat u(m) (chunk_edges), so that they count none.
  pure subroutine row_edges(k, m, near, u, x, y, ri, rs, n_out)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    real(wp), intent(in) :: near, u(0:chunk, 2)
    real(wp), intent(inout) :: x(chunk), y(chunk), ri(chunk), rs(chunk)
    integer, intent(out) :: n_out
    ! (edge_loop/iem_edge_near.inc's variables)
    real(wp) :: par, perp, l0, il0, d, h, e, a, b, li, st
    integer :: c, past
    n_out = 0
    l0 = k%lx
    il0 = k%il0(1)
    do c = 1, padded(m)
      par = u(c, 1) - u(c - 1, 1)
      perp = u(c, 2) - u(c - 1, 2)
      include 'edge_loop/iem_edge_near.inc'
      x(c) = a
      y(c) = b
      ri(c) = li
      rs(c) = st
      n_out = n_out + past
    end do
    if (n_out > 0) call row_far(k, m, u, x, y, ri, rs)
  end subroutine row_edges

  !> n rounded up to a whole number of the widest vectors (8 values), at most a chunk: the
  !> edge loops' length (their remainders ran one edge at a time).
  pure integer function padded(n)
    integer, intent(in) :: n
    padded = min(chunk, 8*((n + 7)/8))
  end function padded

  !> row_edges' values of a row's edges past edge_near's range, measured again (edge_far).
  pure subroutine row_far(k, m, u, x, y, ri, rs)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    real(wp), intent(in) :: u(0:chunk, 2)
    real(wp), intent(inout) :: x(chunk), y(chunk), ri(chunk), rs(chunk)
    integer :: c
    do c = 1, m
      call edge_far(u(c, 1) - u(c - 1, 1), u(c, 2) - u(c - 1, 2), k%lx, k%il0(1), x(c), y(c), &
                    ri(c), rs(c))
    end do
  end subroutine row_far

  !> An edge of reference length l0 (inverse il0) whose end moved by par along the edge and
  !> perp across it, relative to its start: its unit vector's components along (a) and across
  !> (b), its inverse length li and engineering strain st, the same whichever of edge_near
  !> and edge_far measures it.
  elemental subroutine edge_measure(par, perp, l0, il0, a, b, li, st)
    real(wp), intent(in) :: par, perp, l0, il0
    real(wp), intent(out) :: a, b, li, st
    integer :: n_far
    n_far = 0
    call edge_near(par, perp, l0, il0, near_limit, a, b, li, st, n_far)
    if (n_far > 0) call edge_far(par, perp, l0, il0, a, b, li, st)
  end subroutine edge_measure

  !> The largest |(l/l0)^2 - 1| of an edge that edge_near measures (near_limit) and whose
  !> strain st has passed neither a tension onset on_t (st > on_t) nor a crushing onset on_c
  !> (-st > on_c), whatever the round-off: a relative margin of 1e-6 inside the onsets (a
  !> huge onset sets no limit). One limit for both signs (an edge stretched or shortened by
  !> less than the nearer onset), so that the edges' count costs no more than without them.
  pure real(wp) function edge_limit(on_t, on_c) result(near)
    real(wp), intent(in) :: on_t, on_c
    real(wp), parameter :: margin = 1.0e-6_wp
    near = near_limit
    ! st > on_t where (l/l0)^2 - 1 > (1 + on_t)^2 - 1
    if (on_t < 1.0_wp) near = min(near, max(on_t*(2.0_wp + on_t), 0.0_wp)*(1.0_wp - margin))
    ! -st > on_c where (l/l0)^2 - 1 < (1 - on_c)^2 - 1 (never for on_c >= 1)
    if (on_c < 1.0_wp) near = min(near, max(on_c*(2.0_wp - on_c), 0.0_wp)*(1.0_wp - margin))
  end function edge_limit

  !> edge_measure's values of an edge whose squared stretch differs from 1 by at most
  !> near_limit (strains within about +-3%), by multiplications alone; n_out counts the
  !> edges whose |(l/l0)^2 - 1| passes near (<= near_limit: among them those for edge_far,
  !> whose values here are not used). docs/model.md, "Edge measures", gives the accuracy.
  elemental subroutine edge_near(par, perp, l0, il0, near, a, b, li, st, n_out)
    real(wp), intent(in) :: par, perp, l0, il0, near
    real(wp), intent(out) :: a, b, li, st
    integer, intent(inout) :: n_out
    real(wp) :: d, h, e
    integer :: past
    include 'edge_loop/iem_edge_near.inc'
    n_out = n_out + past
  end subroutine edge_near

  !> edge_measure's values of an edge past edge_near's range (those within it left as they
  !> are), with a square root and divisions.
  elemental subroutine edge_far(par, perp, l0, il0, a, b, li, st)
    real(wp), intent(in) :: par, perp, l0, il0
    real(wp), intent(inout) :: a, b, li, st
    real(wp) :: d, l, wa
    d = (par*(2.0_wp*l0 + par) + perp*perp)*(il0*il0)
    if (.not. abs(d) > near_limit) return
    wa = l0 + par
    l = sqrt(wa*wa + perp*perp)
    li = 1.0_wp/l
    a = wa*li
    b = perp*li
    ! l/l0 - 1 without its cancellation
    st = d/(1.0_wp + l*il0)
  end subroutine edge_far

  !> The elastic law of a cell of constants k as five coefficients, the same form for both
  !> cells: g_q = c(1) eps_q + c(2) (eps_{q-1} + eps_{q+1}) + c(3) eps_{q+2} and
  !> t_q = c(4) s_q + c(5) (s_{q+2} - s_{q-1} - s_{q+1}) (docs/model.md: the paper's cell has
  !> c(3) = c(5) = 0; the bending-corrected cell's mean shear couples the four corners).
  pure function law_coefficients(k) result(c)
    type(cell_constants_t), intent(in) :: k
    real(wp) :: c(5)
    if (k%law == law_bending) then
      c = [k%ce + 2.0_wp*k%ch + 2.0_wp*k%cb, 2.0_wp*k%ch, k%ce + 2.0_wp*k%ch - 2.0_wp*k%cb, &
           0.5_wp*k%cg, 0.5_wp*k%cg]
    else
      c = [2.0_wp*k%ce + 4.0_wp*k%ch, 2.0_wp*k%ch, 0.0_wp, 2.0_wp*k%cg, 0.0_wp]
    end if
  end function law_coefficients

  !> The stiffness damping of a chunk's elastic cells (law coefficients lc): beta times the
  !> cell law of the strain and shear rates of the velocities bw, tw as edge stresses hd and
  !> corner stresses ud, and the damping power pw = their product with the rates of the
  !> velocities bp, tp (the same as bw, tw unless the damping acts on filtered velocities);
  !> with mid, the power of the stresses of w - mid (p - w) instead (w: bw, tw; p: bp, tp).
  pure subroutine damping_stresses(k, m, bot, top, v, lc, beta, bw, tw, bp, tp, hd, ud, pw, mid)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    type(edge_row_t), intent(in) :: bot, top
    type(edge_col_t), intent(in) :: v
    real(wp), intent(in) :: lc(chunk, 5), beta
    real(wp), intent(in) :: bw(0:chunk, 2), tw(0:chunk, 2), bp(0:chunk, 2), tp(0:chunk, 2)
    real(wp), intent(out) :: hd(chunk, 4), ud(chunk, 4), pw(chunk)
    !> The power's damping velocity w - mid (p - w) (default 0: w, as the stresses')
    real(wp), intent(in), optional :: mid
    real(wp) :: d(chunk, 4), r(chunk, 4), dp(chunk, 4), rp(chunk, 4), mu
    integer :: c
    call strain_rates(k, m, bot, top, v, bw, tw, d, r)
    call strain_rates(k, m, bot, top, v, bp, tp, dp, rp)
    do c = 1, m
      hd(c, 1) = beta*(lc(c, 1)*d(c, 1) + lc(c, 2)*(d(c, 4) + d(c, 2)) + lc(c, 3)*d(c, 3))
      hd(c, 2) = beta*(lc(c, 1)*d(c, 2) + lc(c, 2)*(d(c, 1) + d(c, 3)) + lc(c, 3)*d(c, 4))
      hd(c, 3) = beta*(lc(c, 1)*d(c, 3) + lc(c, 2)*(d(c, 2) + d(c, 4)) + lc(c, 3)*d(c, 1))
      hd(c, 4) = beta*(lc(c, 1)*d(c, 4) + lc(c, 2)*(d(c, 3) + d(c, 1)) + lc(c, 3)*d(c, 2))
      ud(c, 1) = beta*(lc(c, 4)*r(c, 1) + lc(c, 5)*(r(c, 3) - r(c, 4) - r(c, 2)))
      ud(c, 2) = beta*(lc(c, 4)*r(c, 2) + lc(c, 5)*(r(c, 4) - r(c, 1) - r(c, 3)))
      ud(c, 3) = beta*(lc(c, 4)*r(c, 3) + lc(c, 5)*(r(c, 1) - r(c, 2) - r(c, 4)))
      ud(c, 4) = beta*(lc(c, 4)*r(c, 4) + lc(c, 5)*(r(c, 2) - r(c, 3) - r(c, 1)))
      pw(c) = hd(c, 1)*dp(c, 1) + hd(c, 2)*dp(c, 2) + hd(c, 3)*dp(c, 3) + hd(c, 4)*dp(c, 4) + &
              ud(c, 1)*rp(c, 1) + ud(c, 2)*rp(c, 2) + ud(c, 3)*rp(c, 3) + ud(c, 4)*rp(c, 4)
    end do
    mu = 0.0_wp
    if (present(mid)) mu = mid
    if (mu == 0.0_wp) return
    ! the power of the damping stresses of w - mu (p - w): the stresses are linear in the
    ! rates, so it is (1 + mu) times that of w's less mu times beta p's quadratic form
    do c = 1, m
      pw(c) = (1.0_wp + mu)*pw(c) - mu*beta*( &
              lc(c, 1)*(dp(c, 1)**2 + dp(c, 2)**2 + dp(c, 3)**2 + dp(c, 4)**2) + &
              2.0_wp*lc(c, 2)*(dp(c, 1)*dp(c, 2) + dp(c, 2)*dp(c, 3) + dp(c, 3)*dp(c, 4) + &
                               dp(c, 4)*dp(c, 1)) + &
              2.0_wp*lc(c, 3)*(dp(c, 1)*dp(c, 3) + dp(c, 2)*dp(c, 4)) + &
              lc(c, 4)*(rp(c, 1)**2 + rp(c, 2)**2 + rp(c, 3)**2 + rp(c, 4)**2) + &
              2.0_wp*lc(c, 5)*(rp(c, 1)*rp(c, 3) + rp(c, 2)*rp(c, 4) - rp(c, 1)*rp(c, 2) - &
                               rp(c, 2)*rp(c, 3) - rp(c, 3)*rp(c, 4) - rp(c, 4)*rp(c, 1)))
    end do
  end subroutine damping_stresses

  !> Edge strain rates d and corner shear rates r of a chunk's cells between the node rows
  !> bot, top (vertical edges v) for the velocities wb, wt of the bottom and top node rows.
  pure subroutine strain_rates(k, m, bot, top, v, wb, wt, d, r)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    type(edge_row_t), intent(in) :: bot, top
    type(edge_col_t), intent(in) :: v
    real(wp), intent(in) :: wb(0:chunk, 2), wt(0:chunk, 2)
    real(wp), intent(out) :: d(chunk, 4), r(chunk, 4)
    real(wp) :: e1x, e1y, e2x, e2y, e3x, e3y, e4x, e4y, i1, i2, i3, i4, s1, s2, s3, s4
    real(wp) :: q1x, q1y, q2x, q2y, q3x, q3y, q4x, q4y, ilx, ily
    integer :: c
    ilx = k%il0(1)
    ily = k%il0(2)
    do c = 1, m
      e1x = bot%x(c)
      e1y = bot%y(c)
      e2x = v%x(c)
      e2y = v%y(c)
      e3x = -top%x(c)
      e3y = -top%y(c)
      e4x = -v%x(c - 1)
      e4y = -v%y(c - 1)
      i1 = bot%li(c)
      i2 = v%li(c)
      i3 = top%li(c)
      i4 = v%li(c - 1)
      s1 = -(e1x*e4x + e1y*e4y)
      s2 = -(e2x*e1x + e2y*e1y)
      s3 = -(e3x*e2x + e3y*e2y)
      s4 = -(e4x*e3x + e4y*e3y)
      ! velocity differences along the cell's edges (bottom, right, top, left)
      q1x = wb(c, 1) - wb(c - 1, 1)
      q1y = wb(c, 2) - wb(c - 1, 2)
      q2x = wt(c, 1) - wb(c, 1)
      q2y = wt(c, 2) - wb(c, 2)
      q3x = -(wt(c, 1) - wt(c - 1, 1))
      q3y = -(wt(c, 2) - wt(c - 1, 2))
      q4x = -(wt(c - 1, 1) - wb(c - 1, 1))
      q4y = -(wt(c - 1, 2) - wb(c - 1, 2))
      d(c, 1) = (e1x*q1x + e1y*q1y)*ilx
      d(c, 2) = (e2x*q2x + e2y*q2y)*ily
      d(c, 3) = (e3x*q3x + e3y*q3y)*ilx
      d(c, 4) = (e4x*q4x + e4y*q4y)*ily
      ! the rate of s_q: a_q . (rate of edge q) + b_q . (rate of reversed edge q-1)
      r(c, 1) = ((-e4x - s1*e1x)*i1)*q1x + ((-e4y - s1*e1y)*i1)*q1y &
                - ((e1x + s1*e4x)*i4)*q4x - ((e1y + s1*e4y)*i4)*q4y
      r(c, 2) = ((-e1x - s2*e2x)*i2)*q2x + ((-e1y - s2*e2y)*i2)*q2y &
                - ((e2x + s2*e1x)*i1)*q1x - ((e2y + s2*e1y)*i1)*q1y
      r(c, 3) = ((-e2x - s3*e3x)*i3)*q3x + ((-e2y - s3*e3y)*i3)*q3y &
                - ((e3x + s3*e2x)*i2)*q2x - ((e3y + s3*e2y)*i2)*q2y
      r(c, 4) = ((-e3x - s4*e4x)*i4)*q4x + ((-e3y - s4*e4y)*i4)*q4y &
                - ((e4x + s4*e3x)*i3)*q3x - ((e4y + s4*e3y)*i3)*q3y
    end do
  end subroutine strain_rates

  !> The general path over a chunk of m cells between the node rows bot, top (vertical edges
  !> v; the damping velocities bw, tw, and with filtered damping the velocities bp, tp, of
  !> its node rows 0..m): per cell its shear measures and their gradients in arrays, the cell
  !> law (nonlinear with nl, by material with ks), fracture (only with fr: dmg marks the
  !> n_dmg cells it reached), damping (only when damped) and the corner forces fx, fy(cell,
  !> corner).
  pure subroutine chunk_general(k, m, bot, top, v, damped, filtered, beta, bw, tw, bp, tp, fx, &
                                fy, en, pw, dmg, n_dmg, nl, c_first, accept, ks, mat, fr, time, &
                                energies, mid)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    logical, intent(in) :: damped, filtered
    real(wp), intent(in) :: beta
    type(edge_row_t), intent(in) :: bot, top
    type(edge_col_t), intent(in) :: v
    real(wp), intent(in) :: bw(0:chunk, 2), tw(0:chunk, 2), bp(0:chunk, 2), tp(0:chunk, 2)
    real(wp), intent(out) :: fx(chunk, 4), fy(chunk, 4), en(chunk), pw(chunk)
    logical, intent(out) :: dmg(chunk)
    integer, intent(out) :: n_dmg
    !> Nonlinear springs, the index of the chunk's first cell, and whether to commit.
    type(nonlinear_springs_t), intent(inout), optional :: nl
    integer, intent(in), optional :: c_first
    logical, intent(in), optional :: accept
    !> Several materials: the constants of each and the material of each cell of the chunk.
    type(cell_constants_t), intent(in), optional :: ks(:)
    integer, intent(in), optional :: mat(:)
    !> Fracture state and the time of the state (committed with accept).
    type(fracture_t), intent(inout), optional :: fr
    real(wp), intent(in), optional :: time
    !> Whether the nonlinear springs' energies en are wanted (default: yes; else en = 0).
    logical, intent(in), optional :: energies
    !> With filtered damping: the power's damping velocity w - mid (p - w) (default 0: w).
    real(wp), intent(in), optional :: mid
    ! per cell: unit edge vectors e, shear gradients a (d s/d a) and b (d s/d b), strains ep
    ! and shear measures s, generalised stresses g (edges) and t (corners), and the rates
    real(wp) :: ex(chunk, 4), ey(chunk, 4), ax(chunk, 4), ay(chunk, 4)
    real(wp) :: bx(chunk, 4), by(chunk, 4), ep(chunk, 4), s(chunk, 4), g(chunk, 4), t(chunk, 4)
    real(wp) :: d(chunk, 4), r(chunk, 4), gd(chunk, 4), td(chunk, 4)
    real(wp) :: e1x, e1y, e2x, e2y, e3x, e3y, e4x, e4y, i1, i2, i3, i4
    real(wp) :: s1, s2, s3, s4, ilx, ily
    real(wp) :: fe(chunk, 4), fs(chunk, 4), dp(chunk, 4), rp(chunk, 4), gm(chunk, 4), tm(chunk, 4)
    real(wp) :: dm(chunk, 4), rm(chunk, 4)
    integer :: c
    logical :: mid_on

    ilx = k%il0(1)
    ily = k%il0(2)
    do c = 1, m
      ! the cell's edges: bottom, right, reversed top, reversed left
      e1x = bot%x(c)
      e1y = bot%y(c)
      e2x = v%x(c)
      e2y = v%y(c)
      e3x = -top%x(c)
      e3y = -top%y(c)
      e4x = -v%x(c - 1)
      e4y = -v%y(c - 1)
      i1 = bot%li(c)
      i2 = v%li(c)
      i3 = top%li(c)
      i4 = v%li(c - 1)
      ep(c, 1) = bot%st(c)
      ep(c, 2) = v%st(c)
      ep(c, 3) = top%st(c)
      ep(c, 4) = v%st(c - 1)
      ! shear measures s = sin(gamma) at corners 1..4 (corner q joins edges q and q-1)
      s1 = -(e1x*e4x + e1y*e4y)
      s2 = -(e2x*e1x + e2y*e1y)
      s3 = -(e3x*e2x + e3y*e2y)
      s4 = -(e4x*e3x + e4y*e3y)
      s(c, 1) = s1
      s(c, 2) = s2
      s(c, 3) = s3
      s(c, 4) = s4
      ex(c, 1) = e1x
      ex(c, 2) = e2x
      ex(c, 3) = e3x
      ex(c, 4) = e4x
      ey(c, 1) = e1y
      ey(c, 2) = e2y
      ey(c, 3) = e3y
      ey(c, 4) = e4y
      ! d s_q / d a (a: edge q) and d s_q / d b (b: reversed edge q-1)
      ax(c, 1) = (-e4x - s1*e1x)*i1
      ax(c, 2) = (-e1x - s2*e2x)*i2
      ax(c, 3) = (-e2x - s3*e3x)*i3
      ax(c, 4) = (-e3x - s4*e4x)*i4
      ay(c, 1) = (-e4y - s1*e1y)*i1
      ay(c, 2) = (-e1y - s2*e2y)*i2
      ay(c, 3) = (-e2y - s3*e3y)*i3
      ay(c, 4) = (-e3y - s4*e4y)*i4
      bx(c, 1) = (e1x + s1*e4x)*i4
      bx(c, 2) = (e2x + s2*e1x)*i1
      bx(c, 3) = (e3x + s3*e2x)*i2
      bx(c, 4) = (e4x + s4*e3x)*i3
      by(c, 1) = (e1y + s1*e4y)*i4
      by(c, 2) = (e2y + s2*e1y)*i1
      by(c, 3) = (e3y + s3*e2y)*i2
      by(c, 4) = (e4y + s4*e3y)*i3
    end do
    if (present(nl)) then
      call nonlinear_law(nl, c_first, m, ep, s, accept, g, t, en, mat, energies)
    else
      if (present(ks)) then
        call cell_law_mixed(ks, mat, m, ep, s, g, t)
      else
        call cell_law(k, m, ep, s, g, t)
      end if
      do c = 1, m
        en(c) = 0.5_wp*(g(c, 1)*ep(c, 1) + g(c, 2)*ep(c, 2) + g(c, 3)*ep(c, 3) + &
                        g(c, 4)*ep(c, 4) + t(c, 1)*s(c, 1) + t(c, 2)*s(c, 2) + &
                        t(c, 3)*s(c, 3) + t(c, 4)*s(c, 4))
      end do
    end if
    n_dmg = 0
    dmg(1:m) = .false.
    if (present(fr)) then
      if (present(ks)) then
        call fracture_chunk(fr, c_first, m, k, ep, s, accept, time, g, t, en, fe, fs, dmg, &
                            n_dmg, ks, mat)
      else
        call fracture_chunk(fr, c_first, m, k, ep, s, accept, time, g, t, en, fe, fs, dmg, &
                            n_dmg)
      end if
    end if
    pw(1:m) = 0.0_wp
    if (damped) then
      call strain_rates(bw, tw, d, r)
      call damping_law(d, r, gd, td)
      ! the damping power is f_damp . v: with filtered damping velocities, the strain rates of
      ! the velocities themselves are needed too
      mid_on = .false.
      if (filtered) then
        call strain_rates(bp, tp, dp, rp)
        if (present(mid)) mid_on = mid /= 0.0_wp
        if (mid_on) then
          ! (velocity Verlet) the power takes the damping stresses of w - mid (p - w)
          dm(1:m, :) = d(1:m, :) - mid*(dp(1:m, :) - d(1:m, :))
          rm(1:m, :) = r(1:m, :) - mid*(rp(1:m, :) - r(1:m, :))
          call damping_law(dm, rm, gm, tm)
        end if
        d(1:m, :) = dp(1:m, :)
        r(1:m, :) = rp(1:m, :)
      end if
      do c = 1, m
        pw(c) = cell_power(c, gd, td)
        g(c, :) = g(c, :) + beta*gd(c, :)
        t(c, :) = t(c, :) + beta*td(c, :)
      end do
      if (mid_on) then
        do c = 1, m
          pw(c) = cell_power(c, gm, tm)
        end do
      end if
    end if
    do c = 1, m
      ! edge forces per unit reference length along the unit vectors: corner q+1 gets
      ! +g_q e_q + t_q a_q, corner q gets -g_q e_q - t_q (a_q + b_q), corner q-1 gets t_q b_q
      g(c, 1) = g(c, 1)*ilx
      g(c, 2) = g(c, 2)*ily
      g(c, 3) = g(c, 3)*ilx
      g(c, 4) = g(c, 4)*ily
      fx(c, 1) = -g(c, 1)*ex(c, 1) - t(c, 1)*(ax(c, 1) + bx(c, 1)) + g(c, 4)*ex(c, 4) &
                 + t(c, 4)*ax(c, 4) + t(c, 2)*bx(c, 2)
      fy(c, 1) = -g(c, 1)*ey(c, 1) - t(c, 1)*(ay(c, 1) + by(c, 1)) + g(c, 4)*ey(c, 4) &
                 + t(c, 4)*ay(c, 4) + t(c, 2)*by(c, 2)
      fx(c, 2) = -g(c, 2)*ex(c, 2) - t(c, 2)*(ax(c, 2) + bx(c, 2)) + g(c, 1)*ex(c, 1) &
                 + t(c, 1)*ax(c, 1) + t(c, 3)*bx(c, 3)
      fy(c, 2) = -g(c, 2)*ey(c, 2) - t(c, 2)*(ay(c, 2) + by(c, 2)) + g(c, 1)*ey(c, 1) &
                 + t(c, 1)*ay(c, 1) + t(c, 3)*by(c, 3)
      fx(c, 3) = -g(c, 3)*ex(c, 3) - t(c, 3)*(ax(c, 3) + bx(c, 3)) + g(c, 2)*ex(c, 2) &
                 + t(c, 2)*ax(c, 2) + t(c, 4)*bx(c, 4)
      fy(c, 3) = -g(c, 3)*ey(c, 3) - t(c, 3)*(ay(c, 3) + by(c, 3)) + g(c, 2)*ey(c, 2) &
                 + t(c, 2)*ay(c, 2) + t(c, 4)*by(c, 4)
      fx(c, 4) = -g(c, 4)*ex(c, 4) - t(c, 4)*(ax(c, 4) + bx(c, 4)) + g(c, 3)*ex(c, 3) &
                 + t(c, 3)*ax(c, 3) + t(c, 1)*bx(c, 1)
      fy(c, 4) = -g(c, 4)*ey(c, 4) - t(c, 4)*(ay(c, 4) + by(c, 4)) + g(c, 3)*ey(c, 3) &
                 + t(c, 3)*ay(c, 3) + t(c, 1)*by(c, 1)
    end do
  contains

    !> The damping law's stresses gq, tq (without beta) of the chunk's edge and shear rates
    !> dq, rq: the cells' elastic law, their damaged law where fracture has damaged them.
    pure subroutine damping_law(dq, rq, gq, tq)
      real(wp), intent(in) :: dq(chunk, 4), rq(chunk, 4)
      real(wp), intent(out) :: gq(chunk, 4), tq(chunk, 4)
      integer :: i
      if (present(ks)) then
        call cell_law_mixed(ks, mat, m, dq, rq, gq, tq)
      else
        call cell_law(k, m, dq, rq, gq, tq)
      end if
      if (n_dmg == 0) return
      do i = 1, m
        if (.not. dmg(i)) cycle
        if (present(ks)) then
          call damaged_cell(ks(mat(i)), dq(i, :), rq(i, :), fe(i, :), fs(i, :), gq(i, :), &
                            tq(i, :))
        else
          call damaged_cell(k, dq(i, :), rq(i, :), fe(i, :), fs(i, :), gq(i, :), tq(i, :))
        end if
      end do
    end subroutine damping_law

    !> Cell i's damping power: beta times its stresses gq, tq by the rates d, r.
    pure real(wp) function cell_power(i, gq, tq) result(p)
      integer, intent(in) :: i
      real(wp), intent(in) :: gq(chunk, 4), tq(chunk, 4)
      p = beta*(gq(i, 1)*d(i, 1) + gq(i, 2)*d(i, 2) + gq(i, 3)*d(i, 3) + gq(i, 4)*d(i, 4) + &
                tq(i, 1)*r(i, 1) + tq(i, 2)*r(i, 2) + tq(i, 3)*r(i, 3) + tq(i, 4)*r(i, 4))
    end function cell_power

    !> Edge strain rates d and shear rates r of the chunk's cells for the velocities wb, wt
    !> of the bottom and top node rows.
    pure subroutine strain_rates(wb, wt, d_, r_)
      real(wp), intent(in) :: wb(0:chunk, 2), wt(0:chunk, 2)
      real(wp), intent(out) :: d_(chunk, 4), r_(chunk, 4)
      real(wp) :: q1x, q1y, q2x, q2y, q3x, q3y, q4x, q4y
      integer :: i
      do i = 1, m
        ! velocity differences along the cell's edges (bottom, right, top, left)
        q1x = wb(i, 1) - wb(i - 1, 1)
        q1y = wb(i, 2) - wb(i - 1, 2)
        q2x = wt(i, 1) - wb(i, 1)
        q2y = wt(i, 2) - wb(i, 2)
        q3x = -(wt(i, 1) - wt(i - 1, 1))
        q3y = -(wt(i, 2) - wt(i - 1, 2))
        q4x = -(wt(i - 1, 1) - wb(i - 1, 1))
        q4y = -(wt(i - 1, 2) - wb(i - 1, 2))
        d_(i, 1) = (ex(i, 1)*q1x + ey(i, 1)*q1y)*ilx
        d_(i, 2) = (ex(i, 2)*q2x + ey(i, 2)*q2y)*ily
        d_(i, 3) = (ex(i, 3)*q3x + ey(i, 3)*q3y)*ilx
        d_(i, 4) = (ex(i, 4)*q4x + ey(i, 4)*q4y)*ily
        r_(i, 1) = ax(i, 1)*q1x + ay(i, 1)*q1y - bx(i, 1)*q4x - by(i, 1)*q4y
        r_(i, 2) = ax(i, 2)*q2x + ay(i, 2)*q2y - bx(i, 2)*q1x - by(i, 2)*q1y
        r_(i, 3) = ax(i, 3)*q3x + ay(i, 3)*q3y - bx(i, 3)*q2x - by(i, 3)*q2y
        r_(i, 4) = ax(i, 4)*q4x + ay(i, 4)*q4y - bx(i, 4)*q3x - by(i, 4)*q3y
      end do
    end subroutine strain_rates
  end subroutine chunk_general
end module iem_cell_chunk
