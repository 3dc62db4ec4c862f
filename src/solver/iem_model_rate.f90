!> The rate evaluation of the lattice model (model_rate, documented at its interface in
!> iem_model.f90): the cell forces, with or without the overlapped halo exchange, the loads
!> and reactions, the powers, and the pass over the owned nodes.
submodule (iem_model) iem_model_rate
  use mpi_f08, only: MPI_Wait, MPI_Test, MPI_STATUS_IGNORE, MPI_F_sync_reg
  use iem_timers, only: timer_switch, t_force, t_halo, t_update
  use iem_node_pass, only: accelerations_in_place, mass_damping_powers
  use iem_node_pass_filtered, only: rk4_filtered_first, rk4_filtered_mid, rk4_filtered_last
  use iem_cell_table, only: cell_table_t
  implicit none

contains

  !> Documented at its interface in iem_model.f90.
  module procedure model_rate
    integer :: l, b, comp, n, s
    logical :: accept, keep, timed, energies, ready

    ! cell forces (internal + stiffness damping) summed per node in ascending cell order, so
    ! bitwise the same on any number of ranks; energy and damping power of counted cells
    energies = .false.
    keep = .false.
    if (present(commit)) then
      energies = commit .and. this%energies_due
      keep = commit
    end if
    if (present(record)) then
      if (record) energies = .true.
    end if
    if (energies) call this%en_sum%reset()
    accept = .false.
    if (present(commit)) accept = commit
    ! the damping powers' terms exist only with that damping (set after init: made once here)
    call model_damping_arrays(this, lat)
    ! the cells' forces are summed into model%f, or (sum_in_acc) into acc itself; an RK4
    ! stage without stiffness damping goes band by band (bands%active; with halo nodes, when
    ! the halo is exchanged here; 4 values a node: capped damping's 6, even with a ratio of 0,
    ! go in one pass)
    if (this%sum_in_acc) then
      call evaluate(acc)
    else if (present(stage) .and. this%bands%active .and. this%beta == 0.0_wp .and. &
             size(y, 1) == 4 .and. (present(halo) .or. .not. this%split%active)) then
      call evaluate_bands(this%f)
    else
      call evaluate(this%f)
    end if
  contains

    !> evaluate for an RK4 stage without stiffness damping band by band (docs/architecture.md, "The
    !> node pass band by band"): after each band's cells (with halo nodes: of the interior cells,
    !> while the halo values travel), the nodes it completes take their reactions, load powers,
    !> loads, mass damping powers and the stage's pass, once a pending agreement on the last step
    !> has come (until then the bands' passes wait, the cells go on); with halo nodes, the nodes of
    !> D then after the boundary cells. The sums over nodes are formed after the pass in evaluate's
    !> order, so the results are bit for bit evaluate's (but stage%total, a sum over the runs of
    !> nodes, which only says whether all the new values are finite).
    subroutine evaluate_bands(fs)
      real(wp), intent(inout), contiguous :: fs(:, :)
      integer :: band, c1, nb, jb, js, passed
      logical :: known
      p_ext = 0.0_wp
      p_damp = 0.0_wp
      if (present(first_bad)) first_bad = 0
      if (this%split%active) then
        call halo_part(2)
      else if (present(halo)) then
        ! (a rank without halo nodes: the exchange has nothing to move)
        call halo_part(1)
      end if
      call rebuild_loads()
      stage%total = 0.0_wp
      jb = 1
      js = 1
      nb = this%bands%n_bands()
      c1 = 1
      ! a pending agreement on the last step (the state the first pass overwrites) is tested
      ! after each band's cells; the passes wait for it, the cells do not
      known = .not. (present(vote) .and. present(vote_all))
      passed = 0
      do band = 1, nb
        if (this%split%active) then
          call cells(fs, this%split%cells_in, this%split%at_in, &
                     chunk_range=[c1, this%bands%last_chunk(band)])
        else
          call cells(fs, lat%cells, chunk_range=[c1, this%bands%last_chunk(band)])
        end if
        c1 = this%bands%last_chunk(band) + 1
        if (.not. known) then
          call agreement(.false., known)
          if (known .and. .not. vote_all) then
            call rejected_rest(fs, c1)
            return
          end if
        end if
        if (known) call pass_bands(fs, passed, band, jb, js)
      end do
      if (.not. known) then
        call agreement(.true., known)
        if (.not. vote_all) then
          call rejected_rest(fs, c1)
          return
        end if
        call pass_bands(fs, passed, nb, jb, js)
      end if
      if (this%split%active) then
        ! the boundary cells, then D's nodes
        call halo_part(3)
        call cells(fs, this%split%cells_bd, this%split%at_bd)
        call this%split%sum_side(fs)
        p_damp = 0.0_wp
        fs(:, lat%n_owned + 1:lat%n_local) = 0.0_wp
        ! D's nodes, the runs after the bands' (their dofs and loads searched from the first)
        jb = 1
        js = 1
        call pass_bands(fs, passed, nb + 1, jb, js)
      end if
      ! the sums in evaluate's order; the mass damping powers in node order
      call external_power()
      if (this%alpha > 0.0_wp) call sum_in_order(lat%n_owned, this%pw_node, p_damp)
      call imposed_rates(fs)
    end subroutine evaluate_bands

    !> Whether the pending agreement (vote) has come, waiting for it with wait; vote_all is
    !> then every rank's verdict. Timed as halo exchange.
    subroutine agreement(wait, known)
      logical, intent(in) :: wait
      logical, intent(out) :: known
      call timer_switch(t_force, t_halo, timed)
      if (wait) then
        call MPI_Wait(vote, MPI_STATUS_IGNORE)
        known = .true.
      else
        call MPI_Test(vote, known, MPI_STATUS_IGNORE)
      end if
      if (known) call MPI_F_sync_reg(vote_all)
      if (timed) call timer_switch(t_halo, t_force)
    end subroutine agreement

    !> After a rejection found by evaluate_bands with the chunks before c1 evaluated: the
    !> other cells, as evaluate evaluates them, and fs cleared (no pass).
    subroutine rejected_rest(fs, c1)
      real(wp), intent(inout), contiguous :: fs(:, :)
      integer, intent(in) :: c1
      if (this%split%active) then
        call cells(fs, this%split%cells_in, this%split%at_in, &
                   chunk_range=[c1, this%split%cells_in%n_chunks()])
        call halo_part(3)
        call cells(fs, this%split%cells_bd, this%split%at_bd)
      else
        call cells(fs, lat%cells, chunk_range=[c1, lat%cells%n_chunks()])
      end if
      fs = 0.0_wp
    end subroutine rejected_rest

    !> The runs of the bands passed + 1 .. last (run_nodes), timed as state updates; passed
    !> becomes last.
    subroutine pass_bands(fs, passed, last, jb, js)
      real(wp), intent(inout), contiguous :: fs(:, :)
      integer, intent(inout) :: passed, jb, js
      integer, intent(in) :: last
      integer :: r
      if (last <= passed) return
      call timer_switch(t_force, t_update, timed)
      do r = this%bands%run_first(passed + 1), this%bands%run_first(last + 1) - 1
        call run_nodes(fs, this%bands%runs(1, r), this%bands%runs(2, r), jb, js)
      end do
      if (timed) call timer_switch(t_update, t_force)
      passed = last
    end subroutine pass_bands

    !> The nodes lo..hi, whose cell forces are complete in fs: the reactions and reaction
    !> powers of their prescribed dofs, the powers of their loads and the loads, their mass
    !> damping powers (the sums are the caller's), then the stage's pass over them. jb and js
    !> are where the search for their dofs (in bc_by_node) and load slots starts, and are left
    !> after them (runs in ascending order need not search from the first).
    subroutine run_nodes(fs, lo, hi, jb, js)
      real(wp), intent(inout), contiguous :: fs(:, :)
      integer, intent(in) :: lo, hi
      integer, intent(inout) :: jb, js
      real(wp) :: total
      integer :: j0
      call model_run_terms(this, lo, hi, fs, y, t, keep, jb, js, j0, fold)
      associate(n_b => hi - lo + 1)
        select case (stage%stage)
        case (1)
          call rk4_first_pass(n_b, this%alpha, this%mass(lo:hi), stage%wdt, stage%h, &
                              y(:, lo:hi), fs(:, lo:hi), ynew(:, lo:hi), ynext(:, lo:hi))
        case (2, 3)
          call rk4_mid_pass(n_b, this%alpha, this%mass(lo:hi), stage%wdt, stage%h, &
                            y0(:, lo:hi), fs(:, lo:hi), ynew(:, lo:hi), y(:, lo:hi))
        case default
          call rk4_last_pass(n_b, this%alpha, this%mass(lo:hi), stage%wdt, y(:, lo:hi), &
                             fs(:, lo:hi), ynew(:, lo:hi), total)
          stage%total = stage%total + total
        end select
      end associate
    end subroutine run_nodes

    !> The evaluation with the cell forces summed into fs (all zero on entry): the cells, the
    !> loads and reactions, the powers and the pass over the owned nodes, which clears fs or
    !> (sum_in_acc, fs being acc) leaves the accelerations in it. With sum_in_acc, acc itself is
    !> referenced only as fs.
    subroutine evaluate(fs)
      real(wp), intent(inout), contiguous :: fs(:, :)
      ! fs holds zeros here (the node passes below clear what they read), or with cells_done
      ! the cells' forces (one rank, no stiffness damping: their damping power is 0)
      p_damp = 0.0_wp
      ready = .false.
      if (present(cells_done)) ready = cells_done
      if (ready) then
        if (.not. this%sum_in_acc .or. lat%n_local /= lat%n_owned .or. this%beta > 0.0_wp) &
          error stop 'model_rate: cells_done needs the forces in acc, one rank, no beta'
      else if (.not. present(halo)) then
        call cells(fs, lat%cells)
      else if (.not. this%split%active) then
        call halo_part(1)
        call cells(fs, lat%cells)
      else
        ! the interior cells while the halo values travel, then the boundary cells; the nodes
        ! of D get their cells' forces summed in cell order; so does the damping power
        call halo_part(2)
        call cells(fs, this%split%cells_in, this%split%at_in)
        call halo_part(3)
        call cells(fs, this%split%cells_bd, this%split%at_bd)
        call this%split%sum_side(fs)
        p_damp = 0.0_wp
        if (this%beta > 0.0_wp) call counted_cell_powers(lat, this%pw_cell, p_damp)
      end if
      call rebuild_loads()
      ! the cell forces of the prescribed dofs, for the reactions, and the powers at the
      ! evaluated state (before a fused RK4 pass moves y on): of the loads, of the support
      ! reactions (which need the imposed accelerations), of mass damping; the halo nodes'
      ! forces are not used
      do n = 1, size(this%bc_node)
        call this%reaction_terms(n, fs, y, t, this%fext, keep, this%pr_bc(n), this%pr_on(n))
      end do
      fs(:, lat%n_owned + 1:lat%n_local) = 0.0_wp
      do s = 1, size(this%ext_node)
        this%pe_slot(s) = this%slot_power(s, y)
      end do
      call external_power()
      if (this%alpha > 0.0_wp) call mass_damping_powers(lat%n_owned, this%alpha, this%mass, y, &
                                                        this%pw_node, p_damp, this%wd_node, fold)
      ! the loads act as negative cell forces; then the pass over the owned nodes, which clears
      ! f: accelerations, or an RK4 stage's update
      do s = 1, size(this%ext_node)
        l = this%ext_node(s)
        fs(:, l) = fs(:, l) - this%fext(:, s)
      end do
      ! a pending agreement on the state the pass is about to overwrite (RK4's last step)
      if (present(vote) .and. present(vote_all)) then
        call timer_switch(t_force, t_halo, timed)
        call MPI_Wait(vote, MPI_STATUS_IGNORE)
        call MPI_F_sync_reg(vote_all)
        if (timed) call timer_switch(t_halo, t_force)
        if (.not. vote_all) then
          fs = 0.0_wp
          if (present(first_bad)) first_bad = 0
          return
        end if
      end if
      ! the pass over the nodes counts as the state updates (when the caller times the force)
      call timer_switch(t_force, t_update, timed)
      if (present(stage)) then
        if (present(first_bad)) first_bad = 0
        associate(n_o => lat%n_owned, wc => this%omega_cap)
          if (size(y, 1) == 6) then
            ! capped damping's filtered velocities: their rates in the same pass
            select case (stage%stage)
            case (1)
              call rk4_filtered_first(n_o, this%alpha, wc, this%mass, stage%wdt, stage%h, y, &
                                      fs, ynew, ynext)
            case (2, 3)
              call rk4_filtered_mid(n_o, this%alpha, wc, this%mass, stage%wdt, stage%h, y0, &
                                    fs, ynew, y)
            case default
              call rk4_filtered_last(n_o, this%alpha, wc, this%mass, stage%wdt, y, fs, ynew, &
                                     stage%total)
            end select
          else
            select case (stage%stage)
            case (1)
              call rk4_first_pass(n_o, this%alpha, this%mass, stage%wdt, stage%h, y, fs, &
                                  ynew, ynext)
            case (2, 3)
              call rk4_mid_pass(n_o, this%alpha, this%mass, stage%wdt, stage%h, y0, fs, ynew, &
                                y)
            case default
              call rk4_last_pass(n_o, this%alpha, this%mass, stage%wdt, y, fs, ynew, &
                                 stage%total)
            end select
          end if
        end associate
      else
        if (this%sum_in_acc) then
          call accelerations_in_place(lat%n_owned, this%alpha, this%mass, y, fs, kick, first_bad, &
                                      drift)
        else
          call accelerations(lat%n_owned, this%alpha, this%mass, y, fs, acc, kick, first_bad)
        end if
      end if
      if (timed) call timer_switch(t_update, t_force)
      ! prescribed dofs: the imposed accelerations (not kept by a fused RK4 stage: acc unused;
      ! with the forces summed in acc, they go where the pass left the accelerations; not
      ! after a guarded kick that found non-finite velocities: the rates keep what it left)
      if (present(first_bad)) then
        if (first_bad /= 0) return
      end if
      ! (with drift the pass has cleared acc for the next step's forces: the prescribed dofs'
      ! rates are not used there, their values set by the caller)
      if (present(drift)) return
      call imposed_rates(fs)
    end subroutine evaluate

    !> The rates of the prescribed dofs (into fs with sum_in_acc, else into acc when it has
    !> columns) and capped damping's filter rates, after the pass.
    subroutine imposed_rates(fs)
      real(wp), intent(inout), contiguous :: fs(:, :)
      do n = 1, size(this%bc_node)
        b = this%bc_id(n)
        if (t >= this%bc_release(b)) cycle
        comp = this%bc_comp(n)
        if (this%sum_in_acc) then
          fs(comp, this%bc_node(n)) = this%bc_velocity(comp, b)*tf_rate(this%bc_tf(b), t)
        else if (size(acc, 2) > 0) then
          acc(comp, this%bc_node(n)) = this%bc_velocity(comp, b)*tf_rate(this%bc_tf(b), t)
        end if
      end do
      ! capped stiffness damping: the filtered velocity follows v at the rate omega_cap (an
      ! RK4 stage's pass has used them already)
      if (this%omega_cap > 0.0_wp .and. .not. present(stage)) &
        call filter_rates(lat%n_owned, this%omega_cap, y, acc)
    end subroutine imposed_rates

    !> p_ext: the loads' powers, then the reactions' that enter it (model_external_power).
    subroutine external_power()
      p_ext = model_external_power(this)
    end subroutine external_power

    !> The external loads fext at t (model_set_loads).
    subroutine rebuild_loads()
      call model_set_loads(this, t)
    end subroutine rebuild_loads

    !> The halo exchange (1), its start (2) or its finish (3), timed as such.
    subroutine halo_part(part)
      integer, intent(in) :: part
      logical :: switched
      call timer_switch(t_force, t_halo, switched)
      select case (part)
      case (1)
        call halo%exchange(y)
      case (2)
        call halo%start(y)
      case default
        call halo%finish(y)
      end select
      if (switched) call timer_switch(t_halo, t_force)
    end subroutine halo_part

    !> The cell forces of the chunks of table (with at, those of the split's routed chunks;
    !> with chunk_range, only those chunks), summed into fs; their cells' energies added to
    !> en_sum when the evaluation keeps them. The kernel's damping power goes to p_damp, but
    !> with chunk_range (which evaluate_bands uses only without stiffness damping).
    subroutine cells(fs, table, at, chunk_range)
      real(wp), intent(inout), contiguous :: fs(:, :)
      type(cell_table_t), intent(in) :: table
      integer, intent(in), optional, contiguous :: at(:)
      integer, intent(in), optional :: chunk_range(2)
      real(wp) :: pd
      if (energies) then
        call this%cells(lat, table, y, fs, accept, t, this%rows, this%slots, pd, at, &
                        this%en_sum, chunk_range)
      else
        call this%cells(lat, table, y, fs, accept, t, this%rows, this%slots, pd, at, &
                        range=chunk_range)
      end if
      if (.not. present(chunk_range)) p_damp = pd
    end subroutine cells
  end procedure model_rate

  !> The terms pw(1:n) added to p in their order.
  pure subroutine sum_in_order(n, pw, p)
    integer, intent(in) :: n
    real(wp), intent(in) :: pw(:)
    real(wp), intent(inout) :: p
    real(wp) :: sum_p
    integer :: l
    sum_p = p
    do l = 1, n
      sum_p = sum_p + pw(l)
    end do
    p = sum_p
  end subroutine sum_in_order

  !> The sum p of the stiffness damping's powers pw of the cells this rank counts (first
  !> corner owned), in cell order.
  pure subroutine counted_cell_powers(lat, pw, p)
    type(local_lattice_t), intent(in) :: lat
    real(wp), intent(in) :: pw(:)
    real(wp), intent(out) :: p
    real(wp) :: sum_p
    integer :: j, c, m, c0, fc(max_chunk)
    sum_p = 0.0_wp
    do j = 1, lat%cells%n_chunks()
      call lat%first_corners(j, fc, m)
      c0 = lat%cells%chunks(1, j) - 1
      do c = 1, m
        if (fc(c) <= lat%n_owned) sum_p = sum_p + pw(c0 + c)
      end do
    end do
    p = sum_p
  end subroutine counted_cell_powers

  !> Capped stiffness damping: the rates acc(3:4, l) = omega_cap (v - w) of the filtered
  !> velocities w = y(5:6, l) of the nodes 1..n.
  pure subroutine filter_rates(n, omega_cap, y, acc)
    integer, intent(in) :: n
    real(wp), intent(in) :: omega_cap, y(:, :)
    real(wp), intent(inout) :: acc(:, :)
    integer :: l
    do l = 1, n
      acc(3:4, l) = omega_cap*(y(3:4, l) - y(5:6, l))
    end do
  end subroutine filter_rates
end submodule iem_model_rate
