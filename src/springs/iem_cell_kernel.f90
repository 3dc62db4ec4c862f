!> Force kernel of the IEM cell: edge, Poisson and shear springs measured on the current
!> geometry (edge lengths and corner angles), so any rigid motion gives zero force.
!>
!> Strain measures (docs/model.md): edge q, from corner q to corner q+1, has the engineering
!> strain eps_q = l_q/l0_q - 1; corner q (edges q and q-1) has the shear measure
!> s_q = sin(gamma_q) = cos(theta_q), gamma_q = pi/2 - theta_q, computed from the unit edge
!> vectors without any angle function. s = gamma - gamma^3/6 + ..., so the tangent is that of
!> the angle and the shear stress differs from the angle form by gamma^2/6 (2e-5 at 1% shear).
!> The cell law maps (eps, s) linearly to generalised stresses (g, t) = dPi/d(eps, s): the
!> paper's springs or the bending-corrected cell (iem_spring_constants).
module iem_cell_kernel
  use iem_kinds, only: wp, i8
  use iem_spring_constants, only: cell_constants_t
  use iem_nonlinear_springs, only: nonlinear_springs_t
  use iem_cell_laws, only: chunk
  use iem_cell_chunk, only: edge_row_t, edge_col_t, chunk_edges, edge_measure, edge_limit, &
                            chunk_general, law_coefficients, damping_stresses
  use iem_cell_elastic, only: chunk_elastic, chunk_elastic_forces, chunk_elastic_plain, &
                              chunk_elastic_paper, chunk_elastic_plain_energy, &
                              chunk_elastic_tested, onsets_none, onsets_shear, onsets_all
  use iem_fracture, only: fracture_t
  use iem_fracture_kernel, only: chunk_intact, chunk_unhit
  use iem_exact_sum, only: exact_sum_t
  use iem_cell_table, only: cell_table_t, cell_table
  use iem_kernel_rows, only: gather_block, gather_row, gather_rows, gather_filtered, &
                             add_node_forces, &
                             add_routed_forces, add_block_forces, set_aside
  implicit none
  private
  public :: cell_energy, cell_force, cell_forces, cell_strain_measures
  public :: kernel_rows, kernel_slots_t

  !> Node rows the kernel keeps for reuse by the chunk above (a rank's row of up to 64 chunks,
  !> 4096 cells, reuses every row once; wider rows measure their rows twice).
  integer, parameter :: kernel_slots = 64

  !> Which node rows the kernel's slots hold, kept between calls that go on with the sweep
  !> of one table (cell_forces' chunks and slots, with the same rows).
  type :: kernel_slots_t
    !> Each slot's first node (-1: free), number of edges and of edges past chunk_edges' limit;
    !> the next slot to take, and the slot freed by the last chunk (0: none).
    integer :: node(kernel_slots) = -1, m(kernel_slots) = 0, out(kernel_slots) = 0
    integer :: next = 1, spare = 0
    !> The slot each chunk of the table put its top row in (0: none; a slot since taken by
    !> another row is found out by its node).
    integer, allocatable :: at(:)
  end type kernel_slots_t

contains

  !> Strain energy of one cell (J) for corner displacements u(2, 4).
  pure real(wp) function cell_energy(k, u) result(en)
    type(cell_constants_t), intent(in) :: k
    real(wp), intent(in) :: u(2, 4)
    real(wp) :: v(2, 4), f(2, 4), p
    v = 0.0_wp
    call cell_force(k, u, v, 0.0_wp, f, en, p)
  end function cell_energy

  !> Edge strains ep(4) (bottom, right, top, left) and corner shear measures s(4) (SW, SE,
  !> NE, NW) of one cell for corner displacements u(2, 4), as the force kernel measures them.
  pure subroutine cell_strain_measures(k, u, ep, s)
    type(cell_constants_t), intent(in) :: k
    real(wp), intent(in) :: u(2, 4)
    real(wp), intent(out) :: ep(4), s(4)
    real(wp) :: e(2, 4), li
    ! each edge as the kernel measures it (edge_measure): a horizontal edge from its left to
    ! its right node, a vertical one from its bottom to its top node, reversed for the top
    ! and left edges
    call edge_measure(u(1, 2) - u(1, 1), u(2, 2) - u(2, 1), k%lx, k%il0(1), e(1, 1), e(2, 1), &
                      li, ep(1))
    call edge_measure(u(2, 3) - u(2, 2), u(1, 3) - u(1, 2), k%ly, k%il0(2), e(2, 2), e(1, 2), &
                      li, ep(2))
    call edge_measure(u(1, 3) - u(1, 4), u(2, 3) - u(2, 4), k%lx, k%il0(3), e(1, 3), e(2, 3), &
                      li, ep(3))
    call edge_measure(u(2, 4) - u(2, 1), u(1, 4) - u(1, 1), k%ly, k%il0(4), e(2, 4), e(1, 4), &
                      li, ep(4))
    e(:, 3) = -e(:, 3)
    e(:, 4) = -e(:, 4)
    ! corner q joins edge q and edge q-1
    s(1) = -dot_product(e(:, 1), e(:, 4))
    s(2) = -dot_product(e(:, 2), e(:, 1))
    s(3) = -dot_product(e(:, 3), e(:, 2))
    s(4) = -dot_product(e(:, 4), e(:, 3))
  end subroutine cell_strain_measures

  !> Internal force f(2, 4) = dPi/dx of one cell, plus the stiffness-proportional damping force
  !> beta*K*v when beta > 0; returns the strain energy and the damping power f_damp . v.
  pure subroutine cell_force(k, u, v, beta, f, energy, damp_power)
    type(cell_constants_t), intent(in) :: k
    real(wp), intent(in) :: u(2, 4), v(2, 4), beta
    real(wp), intent(out) :: f(2, 4), energy, damp_power
    integer, parameter :: nodes(4, 1) = reshape([1, 2, 3, 4], [4, 1])
    real(wp) :: y(4, 4)
    y(1:2, :) = u
    y(3:4, :) = v
    call cell_forces(k, cell_table(nodes), 4, y, beta, f, energy, damp_power)
  end subroutine cell_force

  !> Nodal forces f(2, :) (internal + stiffness damping; added to f with add) of many cells
  !> for the state y(4, :) = (u, v) of the corner nodes that cells lists, with the strain
  !> energy (only when cell_energy is absent, else 0) and the damping power summed over the
  !> counted cells (those whose first corner is among the first n_owned nodes). Each node's
  !> force is summed over its cells in the order of their numbers, and each cell's
  !> corner forces depend on its corners' values only, so the same cells in the same order
  !> give bitwise the same forces whatever else the list holds. Cells go in the chunks of
  !> cells (iem_cell_table: consecutive cells of a grid row); docs/architecture.md, "The force
  !> kernel", says how a chunk is evaluated.
  !> The stiffness damping acts on the velocities in rows damp_row:damp_row+1 of y (default 3,
  !> the velocities themselves; 5 for the filtered velocities of capped damping); the damping
  !> power is always taken with the velocities (rows 3:4). With nl (nonlinear springs of the
  !> paper's cell, one set per cell of the table) the springs follow their Masing law from
  !> their committed state; with commit = .true. this state y is accepted: every spring's
  !> history moves to it. The energy is then the work done on the springs (stored plus
  !> dissipated), and stiffness damping uses the initial (elastic) stiffness. With ks and
  !> cell_mat (several materials), cell c follows the constants ks(cell_mat(c)) (and its
  !> material's nonlinear law); k then gives only the geometry (lx, ly, il0), the same for all.
  !> With cell_energy and cell_power (one entry a cell; an empty array: not kept), each
  !> cell's energy and (when beta > 0) damping power are also stored (for sums that do not
  !> depend on how the cells are split among ranks); with energy_terms the counted cells'
  !> energies are added to that exact sum instead (the same sums without an array). With fr
  !> (fracture) the cells whose damage has begun or begins follow the damaged law, and with
  !> commit their damage is committed at time (iem_fracture_kernel).
  pure subroutine cell_forces(k, cells, n_owned, y, beta, f, energy, damp_power, damp_row, &
                              nl, commit, ks, cell_mat, cell_energy, cell_power, fr, time, &
                              add, rows, route_at, route, side, energy_terms, chunks, slots, &
                              damaged, power_mid)
    type(cell_constants_t), intent(in) :: k
    !> The cells, in chunks, with their corners.
    type(cell_table_t), intent(in) :: cells
    !> A cell is counted when its first corner is one of the nodes 1..n_owned.
    integer, intent(in) :: n_owned
    real(wp), intent(in), contiguous :: y(:, :)
    real(wp), intent(in) :: beta
    real(wp), intent(inout), contiguous :: f(:, :)
    real(wp), intent(out) :: energy, damp_power
    integer, intent(in), optional :: damp_row
    type(nonlinear_springs_t), intent(inout), optional :: nl
    logical, intent(in), optional :: commit
    type(cell_constants_t), intent(in), optional :: ks(:)
    integer, intent(in), optional, contiguous :: cell_mat(:)
    real(wp), intent(out), optional, contiguous :: cell_energy(:), cell_power(:)
    type(fracture_t), intent(inout), optional :: fr
    real(wp), intent(in), optional :: time
    !> Add the forces to f (which holds zeros, or forces to add to) instead of replacing it.
    logical, intent(in), optional :: add
    !> Work space: node rows (kernel_rows(); made here when absent).
    type(edge_row_t), intent(inout), optional, target :: rows(:)
    !> Routed chunks (iem_cell_split): route_at(j) > 0 when chunk j's corner forces are routed:
    !> corner q of its cell i by route(route_at(j) + 4*(i - 1) + q - 1): 0 added to f, r > 0
    !> stored in side(:, r), < 0 dropped; route_at(j) < 0 when only a few are set aside, the
    !> others added to f as usual: route(a) = n, then n pairs (4*(i - 1) + q, r > 0) in
    !> route(a + 1 .. a + 2n), a = -route_at(j), corner q of cell i stored in side(:, r);
    !> route_at(j) = 0: added to f as usual.
    integer, intent(in), optional, contiguous :: route_at(:), route(:)
    real(wp), intent(inout), optional, contiguous :: side(:, :)
    !> The exact sum the counted cells' energies are added to (then energy is 0).
    type(exact_sum_t), intent(inout), optional :: energy_terms
    !> Only the chunks chunks(1) .. chunks(2) of the table (energy and damp_power are then
    !> theirs alone).
    integer, intent(in), optional :: chunks(2)
    !> The rows' slots, kept for the next call (with rows): a call from a first chunk after 1
    !> takes them from the call before, which left its chunks' top rows in rows (the nodes of
    !> those rows not changed since).
    type(kernel_slots_t), intent(inout), optional :: slots
    !> Whether fracture has damaged some cell (a commit would change its state; fr only).
    logical, intent(out), optional :: damaged
    !> With filtered damping: the damping power is that of the damping stresses of the
    !> filtered velocity w - power_mid (v - w) (velocity Verlet's step middle; default 0: w,
    !> the velocity the forces take).
    real(wp), intent(in), optional :: power_mid
    ! the chunk's bottom and top node rows (0..m): nodes, displacements, damping velocities
    ! (w) and, with filtered damping, the velocities (p)
    integer :: bn(0:chunk), tn(0:chunk), cq(4, chunk)
    real(wp) :: bw(0:chunk, 2), tw(0:chunk, 2)
    real(wp) :: bp(0:chunk, 2), tp(0:chunk, 2)
    ! the node rows of the last chunks, for the chunk above each to reuse as its bottom row
    ! (slot j: its first node, its number of edges; two more rows for other chunks), and the
    ! vertical edges of the chunk
    type(edge_row_t), allocatable, target :: own_rows(:)
    type(edge_row_t), pointer :: rp(:)
    type(edge_col_t) :: v
    integer :: slot_node(kernel_slots), slot_m(kernel_slots), next_slot, spare, hit, ib, it
    ! the slot each chunk's top row went to, and those of the chunks below this one
    integer, allocatable :: chunk_slot(:)
    integer :: sp, sq
    ! each row's edges past chunk_edges' limit (slots, then the two other rows), and the
    ! chunk's: bottom row, top row, vertical edges
    integer :: slot_out(kernel_slots + 2), n_out(3)
    ! the chunk's cells' law coefficients and damping stresses, corner forces, energies,
    ! powers, strains, and those of the general path (fracture: only its damaged cells taken)
    real(wp) :: lc(chunk, 5), hd(chunk, 4), ud(chunk, 4)
    real(wp) :: fx(chunk, 4), fy(chunk, 4), en(chunk), pw(chunk), ep(chunk, 4), s(chunk, 4)
    real(wp) :: gx(chunk, 4), gy(chunk, 4), gen(chunk), gpw(chunk)
    logical :: dmg(chunk), counted(chunk)
    real(wp) :: terms(chunk)
    integer :: n_terms
    integer :: c0, m, i, nc, row, n_dmg, ic, b0, t0, ic_first, ic_last, test
    logical :: damped, filtered, accept, keep_energy, keep_power, by_material, sums, consec
    logical :: keep_terms
    logical :: lean, intact, paper, shear_onset, patched
    real(wp) :: onset(3), lc1(5), near, mid
    integer(i8) :: n_past

    nc = cells%n_cells
    if (present(damaged)) damaged = .false.
    keep_energy = .false.
    keep_power = .false.
    if (present(cell_energy)) keep_energy = size(cell_energy) >= nc
    if (present(cell_power)) keep_power = size(cell_power) >= nc .and. beta > 0.0_wp
    accept = .false.
    if (present(commit)) accept = commit
    damped = beta > 0.0_wp
    row = 3
    if (present(damp_row)) row = damp_row
    filtered = damped .and. row /= 3
    mid = 0.0_wp
    if (present(power_mid) .and. filtered) mid = power_mid
    by_material = present(ks) .and. present(cell_mat)
    bw = 0.0_wp
    tw = 0.0_wp
    bp = 0.0_wp
    tp = 0.0_wp
    lc1 = law_coefficients(k)
    ! the paper's cell: its law has no terms of lc1(3) and lc1(5)
    paper = lc1(3) == 0.0_wp .and. lc1(5) == 0.0_wp
    do i = 1, 5
      lc(:, i) = lc1(i)
    end do
    ! without damping these stay 0
    hd = 0.0_wp
    ud = 0.0_wp
    pw = 0.0_wp
    ! the energy summed over the counted cells: only when the cells' energies are not asked for
    keep_terms = present(energy_terms)
    sums = .not. (present(cell_energy) .or. keep_terms)
    ! the cells' energies (and the elastic cells' strains and shear measures) are formed only
    ! when asked for
    lean = .not. (sums .or. keep_energy .or. keep_terms)
    onset = huge(1.0_wp)
    if (present(fr)) onset = fr%onset_min
    ! the edges' limit: the series' range, and with fracture a little inside its onsets
    near = edge_limit(onset(1), onset(2))
    shear_onset = onset(3) < huge(1.0_wp)
    if (present(add)) then
      if (.not. add) f = 0.0_wp
    else
      f = 0.0_wp
    end if
    energy = 0.0_wp
    damp_power = 0.0_wp
    if (present(rows)) then
      rp => rows
    else
      allocate(own_rows(kernel_slots + 2))
      rp => own_rows
    end if
    slot_node = -1
    slot_m = 0
    slot_out = 0
    next_slot = 1
    spare = 0
    if (present(slots) .and. present(rows) .and. present(chunks)) then
      if (chunks(1) > 1) then
        slot_node = slots%node
        slot_m = slots%m
        slot_out(1:kernel_slots) = slots%out
        next_slot = slots%next
        spare = slots%spare
      end if
      if (allocated(slots%at)) call move_alloc(slots%at, chunk_slot)
    end if
    if (allocated(chunk_slot)) then
      if (size(chunk_slot) < n_chunks()) deallocate(chunk_slot)
    end if
    if (.not. allocated(chunk_slot)) then
      allocate(chunk_slot(n_chunks()))
      chunk_slot = 0
    end if
    ic_first = 1
    ic_last = n_chunks()
    if (present(chunks)) then
      ic_first = chunks(1)
      ic_last = chunks(2)
    end if
    do ic = ic_first, ic_last
      call chunk_of(ic, c0, m, consec, b0, t0)
      ! the chunk's bottom and top rows: a consecutive chunk's bottom row is the slot of the
      ! chunk below when that chunk's top row is this row; its top row goes to a free slot
      ib = kernel_slots + 1
      it = kernel_slots + 2
      hit = 0
      patched = .false.
      if (consec) then
        ! the slots that still hold the top rows of the chunks below (cells%below): the same
        ! row (its slot is hit), or rows whose edges the bottom row's are (patched)
        sp = held(cells%below(1, ic))
        sq = held(cells%below(2, ic))
        if (sp > 0) then
          if (slot_node(sp) == b0 .and. slot_m(sp) == m) hit = sp
        end if
        if (hit == 0 .and. sp > 0) call patch_row(b0, m, sp, sq, rp(ib), patched)
        if (spare > 0) then
          ! the slot the chunk before read its bottom row from: the few slots in use stay in
          ! the core's nearest cache
          it = spare
          spare = 0
        else
          if (next_slot == hit) next_slot = mod(next_slot, kernel_slots) + 1
          it = next_slot
          next_slot = mod(next_slot, kernel_slots) + 1
        end if
        slot_node(it) = t0
        slot_m(it) = m
        chunk_slot(ic) = it
        if (hit > 0) then
          ! the bottom row is read by this chunk only: its slot is free after it
          ib = hit
          slot_node(hit) = -1
          spare = hit
        end if
        if (filtered .and. row == 5 .and. size(y, 1) == 6) then
          ! capped damping: the three pairs of rows of each node read at once
          call gather_filtered(y, m, b0, t0, hit == 0 .and. .not. patched, rp(ib)%u, &
                               rp(it)%u, bw, tw, bp, tp)
        else
          if (hit == 0 .and. .not. patched) call gather_row(y, 1, m, b0, rp(ib)%u)
          call gather_row(y, 1, m, t0, rp(it)%u)
          if (damped) call gather_block(y, row, m, b0, t0, bw, tw)
          if (filtered) call gather_block(y, 3, m, b0, t0, bp, tp)
        end if
      else
        bn(0) = b0
        tn(0) = t0
        do i = 1, m
          bn(i) = cells%corners(2, cells%chunks(6, ic) + i - 1)
          tn(i) = cells%corners(3, cells%chunks(6, ic) + i - 1)
        end do
        call gather_rows(y, 1, m, bn, tn, rp(ib)%u, rp(it)%u)
        if (damped) call gather_rows(y, row, m, bn, tn, bw, tw)
        if (filtered) call gather_rows(y, 3, m, bn, tn, bp, tp)
      end if
      associate(bot => rp(ib), top => rp(it))
      ! the bottom row's count as measured (a slot's: as the top row of the chunk below; a
      ! patched row's: 0, its slots' counts being 0)
      n_out(1) = slot_out(ib)
      if (patched) n_out(1) = 0
      call chunk_edges(k, m, bot, top, hit == 0 .and. .not. patched, near, v, n_out)
      slot_out(it) = n_out(2)
      if (present(nl)) then
        if (by_material) then
          call chunk_general(k, m, bot, top, v, damped, filtered, beta, bw, tw, bp, tp, fx, fy, &
                             en, pw, &
                             dmg, n_dmg, nl, c0, accept, ks, cell_mat(c0:c0 + m - 1), &
                             energies=.not. lean, mid=mid)
        else
          call chunk_general(k, m, bot, top, v, damped, filtered, beta, bw, tw, bp, tp, fx, fy, &
                             en, pw, &
                             dmg, n_dmg, nl, c0, accept, energies=.not. lean, mid=mid)
        end if
      else
        if (by_material) then
          do i = 1, m
            lc(i, :) = law_coefficients(ks(cell_mat(c0 + i - 1)))
          end do
        end if
        if (filtered) then
          call damping_stresses(k, m, bot, top, v, lc, beta, bw, tw, bp, tp, hd, ud, pw, mid)
        else if (damped) then
          call damping_stresses(k, m, bot, top, v, lc, beta, bw, tw, bw, tw, hd, ud, pw)
        end if
        ! with fracture, the onset test a chunk needs: none when no edge has come near a
        ! tension or crushing onset (edge_limit) and no material has a shear onset (no cell
        ! can pass one), the shear onset's alone when only that, else every criterion's
        test = onsets_none
        if (present(fr)) test = merge(onsets_all, merge(onsets_shear, onsets_none, shear_onset), &
                                      sum(n_out) > 0)
        if (lean .and. test == onsets_none) then
          if (damped .or. by_material) then
            call chunk_elastic_forces(k, m, bot, top, v, lc, hd, ud, fx, fy)
          else if (paper) then
            call chunk_elastic_paper(k, m, bot, top, v, lc1, fx, fy)
          else
            call chunk_elastic_plain(k, m, bot, top, v, lc1, fx, fy)
          end if
          intact = .true.
          if (present(fr)) intact = chunk_unhit(fr, c0, m)
        else if (lean) then
          ! without energies: the test counted in the same loop
          call chunk_elastic_tested(k, m, bot, top, v, damped .or. by_material, paper, lc, hd, &
                                    ud, lc1, test, onset, fx, fy, n_past)
          intact = n_past == 0
          if (intact) intact = chunk_unhit(fr, c0, m)
        else
          if (damped .or. by_material) then
            call chunk_elastic(k, m, bot, top, v, lc, hd, ud, fx, fy, en, ep, s)
          else
            call chunk_elastic_plain_energy(k, m, bot, top, v, lc1, fx, fy, en, ep, s)
          end if
          intact = .true.
          if (present(fr)) intact = chunk_intact(fr, c0, m, ep, s)
        end if
        if (present(fr)) then
          ! cells that fracture has reached take the general path's damaged law
          if (.not. intact) then
            if (by_material) then
              call chunk_general(k, m, bot, top, v, damped, filtered, beta, bw, tw, bp, tp, gx, &
                                 gy, &
                                 gen, gpw, dmg, n_dmg, c_first=c0, accept=accept, ks=ks, &
                                 mat=cell_mat(c0:c0 + m - 1), fr=fr, time=time, mid=mid)
            else
              call chunk_general(k, m, bot, top, v, damped, filtered, beta, bw, tw, bp, tp, gx, &
                                 gy, &
                                 gen, gpw, dmg, n_dmg, c_first=c0, accept=accept, fr=fr, &
                                 time=time, mid=mid)
            end if
            if (present(damaged)) damaged = damaged .or. n_dmg > 0
            do i = 1, m
              if (.not. dmg(i)) cycle
              fx(i, :) = gx(i, :)
              fy(i, :) = gy(i, :)
              en(i) = gen(i)
              pw(i) = gpw(i)
            end do
          end if
        end if
      end if
      end associate
      if (routed(ic)) then
        call cells%chunk_corners(ic, cq, m)
        call add_routed_forces(m, cq, route(route_at(ic):), fx, fy, f, side)
      else
        ! the corners set aside go to their side slots, and add nothing (+0) to f
        if (aside(ic)) call set_aside(route(-route_at(ic):), fx, fy, side)
        if (consec) then
          call add_block_forces(m, f(:, b0:b0 + m), f(:, t0:t0 + m), fx, fy)
        else
          call add_node_forces(m, bn, tn, fx, fy, f)
        end if
      end if
      if (sums .or. damped .or. keep_terms) then
        ! the counted cells: those whose first corner is owned
        if (consec) then
          do i = 1, m
            counted(i) = b0 + i - 1 <= n_owned
          end do
        else
          do i = 1, m
            counted(i) = bn(i - 1) <= n_owned
          end do
        end if
        if (sums) then
          do i = 1, m
            if (counted(i)) energy = energy + en(i)
          end do
        end if
        do i = 1, m
          if (counted(i)) damp_power = damp_power + pw(i)
        end do
        if (keep_terms) then
          ! (the counted cells' energies as one array: the exact sum's faster form)
          n_terms = 0
          do i = 1, m
            if (.not. counted(i)) cycle
            n_terms = n_terms + 1
            terms(n_terms) = en(i)
          end do
          call energy_terms%add(terms(1:n_terms))
        end if
      end if
      if (keep_energy) cell_energy(c0:c0 + m - 1) = en(1:m)
      if (keep_power) cell_power(c0:c0 + m - 1) = pw(1:m)
    end do
    if (present(slots)) then
      slots%node = slot_node
      slots%m = slot_m
      slots%out = slot_out(1:kernel_slots)
      slots%next = next_slot
      slots%spare = spare
      call move_alloc(chunk_slot, slots%at)
    end if
  contains

    !> The slot that holds chunk p's top row (0: none, p = 0, or taken since by another row).
    pure integer function held(p) result(s)
      integer, intent(in) :: p
      s = 0
      if (p == 0) return
      s = chunk_slot(p)
      if (s < 1 .or. s > kernel_slots) then
        s = 0
      else if (slot_node(s) /= cells%chunks(5, p) .or. slot_m(s) /= cells%chunks(2, p)) then
        s = 0
      end if
    end function held

    !> A bottom row (first node b, m edges) made up from the top rows of the slots sp and
    !> (when not 0) sq (cells%below): its nodes and edges copied when the two hold them all
    !> between them and have no edge past near, else patched is .false. and nothing is
    !> copied. The values are those chunk_edges would measure for the row: each edge depends
    !> on its two nodes only.
    pure subroutine patch_row(b, m, sp, sq, row, patched)
      integer, intent(in) :: b, m, sp, sq
      type(edge_row_t), intent(inout) :: row
      logical, intent(out) :: patched
      integer :: mid
      ! node c and edge c of the row are node and edge c + b - (its first node) of a slot
      ! (whose edge c ends at its node c); sp holds edges 1 .. mid, sq mid + 1 .. m
      mid = min(m, slot_node(sp) + slot_m(sp) - b)
      patched = slot_node(sp) <= b .and. slot_out(sp) == 0
      if (sq > 0) then
        patched = patched .and. slot_out(sq) == 0 .and. slot_node(sq) + slot_m(sq) >= b + m
      else
        patched = patched .and. mid == m
      end if
      if (.not. patched) return
      row%u(0, :) = rp(sp)%u(b - slot_node(sp), :)
      call copy_edges(1, mid, b - slot_node(sp), rp(sp), row)
      if (sq > 0) call copy_edges(mid + 1, m, b - slot_node(sq), rp(sq), row)
    end subroutine patch_row

    !> Nodes and edges c = first .. last of row to from nodes and edges c + off of row from.
    pure subroutine copy_edges(first, last, off, from, to)
      integer, intent(in) :: first, last, off
      type(edge_row_t), intent(in) :: from
      type(edge_row_t), intent(inout) :: to
      integer :: c
      do c = first, last
        to%u(c, 1) = from%u(c + off, 1)
        to%u(c, 2) = from%u(c + off, 2)
        to%x(c) = from%x(c + off)
        to%y(c) = from%y(c + off)
        to%li(c) = from%li(c + off)
        to%st(c) = from%st(c + off)
      end do
    end subroutine copy_edges

    !> The number of chunks.
    pure integer function n_chunks()
      n_chunks = cells%n_chunks()
    end function n_chunks

    !> Whether chunk j's corner forces are routed.
    pure logical function routed(j)
      integer, intent(in) :: j
      routed = .false.
      if (present(route_at)) routed = route_at(j) > 0
    end function routed

    !> Whether some of chunk j's corner forces are set aside.
    pure logical function aside(j)
      integer, intent(in) :: j
      aside = .false.
      if (present(route_at)) aside = route_at(j) < 0
    end function aside

    !> Chunk j: its first cell, its number of cells, whether its node rows are consecutive,
    !> its first bottom and top nodes.
    pure subroutine chunk_of(j, first, n, cons, b, t)
      integer, intent(in) :: j
      integer, intent(out) :: first, n, b, t
      logical, intent(out) :: cons
      first = cells%chunks(1, j)
      n = cells%chunks(2, j)
      cons = cells%chunks(3, j) == 1
      b = cells%chunks(4, j)
      t = cells%chunks(5, j)
    end subroutine chunk_of
  end subroutine cell_forces

  !> Work space of cell_forces (its node rows), for a caller that keeps it between calls.
  pure function kernel_rows() result(rows)
    type(edge_row_t), allocatable :: rows(:)
    allocate(rows(kernel_slots + 2))
  end function kernel_rows

end module iem_cell_kernel
